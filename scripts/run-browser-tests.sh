#!/usr/bin/env bash
# run-browser-tests.sh [PYTEST ARG]...   The panel's browser tests (pytest -m browser, tests/panel): Debian's
# chromium driven by Playwright for Python, headless, against simulators (docs/panel.md).
#
# Installs what they need when it is missing: the `chromium` package with apt-get (root), and into the active
# Python environment the panel extra's packages and `playwright` (whose wheel carries its own driver; no
# browser is ever downloaded: the tests launch /usr/bin/chromium by executable_path).
# Unlike the main suite, where these tests skip with a reason naming this script, this FAILS when any of them
# was skipped or none ran. Exit status: pytest's when it failed; 1 when a test skipped or none ran; 2 when
# chromium or the packages cannot be installed.
#   PYTHON  the interpreter with the project installed (default: python3 from PATH, e.g. the active venv)
set -u
here=$(cd "$(dirname "$0")" && pwd)
root=$(dirname "$here")
python=${PYTHON:-python3}
python=$(command -v "$python") || { echo "run-browser-tests: no $python on PATH (set PYTHON)" >&2; exit 2; }
cd "$root" || exit 2

if ! [ -x /usr/bin/chromium ]; then
  echo "run-browser-tests: installing Debian's chromium" >&2
  if [ "$(id -u)" -ne 0 ]; then
    echo "run-browser-tests: /usr/bin/chromium is missing; install it as root: apt-get install -y chromium" >&2
    exit 2
  fi
  { apt-get update -q && DEBIAN_FRONTEND=noninteractive apt-get install -y -q chromium; } >&2 || {
    echo "run-browser-tests: apt-get could not install chromium" >&2; exit 2; }
fi
if ! "$python" -c "import playwright.sync_api, starlette, uvicorn, websockets, httpx" 2>/dev/null; then
  echo "run-browser-tests: installing playwright and the panel's packages into $("$python" -c 'import sys; print(sys.prefix)')" >&2
  "$python" -m pip install -q playwright "starlette>=0.37" "uvicorn>=0.30" "websockets>=12" "httpx>=0.27" >&2 || {
    echo "run-browser-tests: pip could not install playwright and the panel's packages" >&2; exit 2; }
fi

report=$(mktemp "${TMPDIR:-/tmp}/browser-tests.XXXXXX.xml") || exit 2
trap 'rm -f "$report"' EXIT
start=$SECONDS
GRIPPERS_BROWSER_TESTS=1 "$python" -m pytest -q -p no:cacheprovider -m browser -rs --junitxml="$report" tests/panel "$@"
status=$?
echo "run-browser-tests: $((SECONDS - start)) s"
[ $status -eq 0 ] || [ $status -eq 5 ] || exit "$status"   # 5: nothing collected, said below

# Count from pytest's own report, not from its console text (scripts/none-skipped.py).
"$python" "$here/none-skipped.py" "$report" run-browser-tests || exit 1
