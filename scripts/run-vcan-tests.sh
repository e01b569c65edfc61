#!/usr/bin/env bash
# run-vcan-tests.sh [PYTEST ARG]...   The SocketCAN tests (pytest -m vcan, all in tests/vcan), run where vcan0
# and vcan1 exist: through scripts/with-vcan, which boots a User-Mode Linux guest when this kernel lacks vcan.
#
# Unlike a plain pytest run, which skips these tests where there is no vcan0 (so the normal suite stays green
# on any machine), this FAILS when any of them was skipped or none ran: CI runs it to prove the CAN side
# really ran. Exit status: pytest's when it failed; 1 when a test skipped or none ran; with-vcan's 3 when vcan
# cannot be provided.
#   PYTHON  the interpreter with the project installed (default: python3 from PATH, e.g. the active venv)
set -u
here=$(cd "$(dirname "$0")" && pwd)
root=$(dirname "$here")
python=${PYTHON:-python3}
python=$(command -v "$python") || { echo "run-vcan-tests: no $python on PATH (set PYTHON)" >&2; exit 2; }
report=$(mktemp "${TMPDIR:-/tmp}/vcan-tests.XXXXXX.xml") || exit 2
trap 'rm -f "$report"' EXIT
cd "$root" || exit 2

start=$SECONDS
# No .pyc writes from the guest: hostfs caches what the host writes at the same time (a concurrent run).
PYTHONDONTWRITEBYTECODE=1 "$here/with-vcan" "$python" -m pytest -q -p no:cacheprovider -m vcan -rs --junitxml="$report" tests/vcan "$@"
status=$?
echo "run-vcan-tests: $((SECONDS - start)) s (guest boot and tests)"
[[ $status -eq 3 || $status -ge 124 ]] && exit "$status"   # with-vcan could not provide vcan / timed out

# Count from pytest's own report, not from its console text (scripts/none-skipped.py).
"$python" "$here/none-skipped.py" "$report" run-vcan-tests || exit 1
exit "$status"
