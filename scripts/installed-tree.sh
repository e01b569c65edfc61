# Sourced by typecheck.sh and build-docs.sh, which both read the package as it installs.
# pyproject maps drivers/ to grippers.drivers and profiles/ to grippers._profiles (package-dir), which tools
# reading the source tree cannot follow; installed_tree DEST lays DEST/grippers out as site-packages has it,
# with symbolic links to the files of this tree, so every `grippers.drivers...` import resolves to them.
installed_tree() {
    local top dest=$1
    top=$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)
    mkdir -p "$dest/grippers"
    for entry in "$top"/grippers/*; do ln -s "$entry" "$dest/grippers/"; done
    ln -s "$top/drivers" "$dest/grippers/drivers"
    ln -s "$top/profiles" "$dest/grippers/_profiles"
}
