#!/usr/bin/env bash
# Run the ROS 2 tests (tests/ros2) against real rclpy, in the environment scripts/setup-ros2.sh builds.
#
# Fails when any of them is skipped: in CI a skipped ROS 2 test is a missing environment, not a pass.
# Each run gets its own ROS_DOMAIN_ID (and discovery stays on this host), so parallel runs and other ROS 2
# programs on the machine do not see each other's nodes.
# Usage: scripts/run-ros2-tests.sh [pytest arguments...]
set -euo pipefail
HERE="$(cd "$(dirname "${BASH_SOURCE[0]}")" && pwd)"
REPO="$(cd "$HERE/.." && pwd)"

eval "$("$HERE/setup-ros2.sh")"
# Domain ids 0..101 are the safe range for Fast DDS's default ports (ROS 2 docs, "The ROS_DOMAIN_ID");
# 1..100 from the process id, unless the caller chose one.
export ROS_DOMAIN_ID="${ROS_DOMAIN_ID:-$(( ($$ % 100) + 1 ))}"
export ROS_AUTOMATIC_DISCOVERY_RANGE=LOCALHOST
echo "run-ros2-tests: ROS_DOMAIN_ID=$ROS_DOMAIN_ID, python $GRIPPERS_ROS2_PYTHON" >&2

cd "$REPO"
report="$(mktemp)"
trap 'rm -f "$report"' EXIT
set +e
"$GRIPPERS_ROS2_PYTHON" -m pytest -p no:cacheprovider -m ros2 -rs --junitxml="$report" tests/ros2 "$@"
rc=$?
set -e
[ $rc -eq 0 ] || exit $rc
"$GRIPPERS_ROS2_PYTHON" "$HERE/none-skipped.py" "$report" run-ros2-tests >&2
