#!/usr/bin/env bash
# Build the documentation site (docs/ + the API reference from the docstrings) with warnings as errors.
# Needs the docs extra: pip install -e '.[docs]' (the test extra includes it). CI runs this script.
#
# The API reference reads the source statically, so mkdocstrings reads the package as installed
# (scripts/installed-tree.sh).
set -euo pipefail
cd "$(dirname "$0")/.."
source scripts/installed-tree.sh
work="$(mktemp -d)"
trap 'rm -rf "$work"' EXIT
installed_tree "$work/src"
out="${1:-$work/site}"
GRIPPERS_DOCS_SOURCE="$work/src" python -m mkdocs build --strict --site-dir "$out"
echo "docs built in $out"
