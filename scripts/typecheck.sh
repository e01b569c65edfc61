#!/usr/bin/env bash
# mypy over the package as it installs. pyproject maps drivers/ to grippers.drivers and profiles/ to
# grippers._profiles (package-dir), which mypy cannot follow from the source tree; a temporary tree of links lays
# the package out as site-packages has it, so every `grippers.drivers...` import resolves to the files we check.
set -euo pipefail
top=$(cd "$(dirname "$0")/.." && pwd)
tree=$(mktemp -d "${TMPDIR:-/tmp}/grippers-mypy.XXXXXX")
trap 'rm -rf "$tree"' EXIT
mkdir "$tree/grippers"
for entry in "$top"/grippers/*; do ln -s "$entry" "$tree/grippers/"; done
ln -s "$top/drivers" "$tree/grippers/drivers"
ln -s "$top/profiles" "$tree/grippers/_profiles"
cd "$tree"
mypy --config-file "$top/pyproject.toml" --cache-dir "$top/.mypy_cache" "$@" grippers
