#!/usr/bin/env bash
# mypy over the package as it installs (scripts/installed-tree.sh says why the tree of links).
set -euo pipefail
top=$(cd "$(dirname "$0")/.." && pwd)
source "$top/scripts/installed-tree.sh"
tree=$(mktemp -d "${TMPDIR:-/tmp}/grippers-mypy.XXXXXX")
trap 'rm -rf "$tree"' EXIT
installed_tree "$tree"
cd "$tree"
mypy --config-file "$top/pyproject.toml" --cache-dir "$top/.mypy_cache" "$@" grippers
