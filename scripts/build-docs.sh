#!/usr/bin/env bash
# Build the documentation site (docs/ + the API reference from the docstrings) with warnings as errors.
# Needs the docs extra: pip install -e '.[docs]' (the test extra includes it). CI runs this script.
#
# The API reference reads the source statically, and the source tree maps drivers/ to grippers.drivers only
# at install time (pyproject.toml [tool.setuptools.package-dir]); so the package is laid out as installed,
# with symbolic links, in a temporary folder that mkdocstrings reads.
set -euo pipefail
cd "$(dirname "$0")/.."
root="$(pwd)"
work="$(mktemp -d)"
trap 'rm -rf "$work"' EXIT
mkdir -p "$work/src/grippers"
for entry in "$root"/grippers/*; do
    ln -s "$entry" "$work/src/grippers/$(basename "$entry")"
done
ln -s "$root/drivers" "$work/src/grippers/drivers"
ln -s "$root/profiles" "$work/src/grippers/_profiles"
out="${1:-$work/site}"
GRIPPERS_DOCS_SOURCE="$work/src" python -m mkdocs build --strict --site-dir "$out"
echo "docs built in $out"
