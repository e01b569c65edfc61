"""The ROS 2 tests need real rclpy and control_msgs: scripts/run-ros2-tests.sh builds them and refuses skips.

Without them (the normal suite), the modules that import rclpy skip with the reason; the tests that check
the behaviour without ROS still run.
"""

from __future__ import annotations

import importlib.util

ROS_MISSING = [
    m
    for m in ("rclpy", "control_msgs", "sensor_msgs", "std_srvs", "diagnostic_msgs", "lifecycle_msgs")
    if importlib.util.find_spec(m) is None
]
SKIP_REASON = (
    f"ROS 2 not available ({', '.join(ROS_MISSING)} missing): run scripts/run-ros2-tests.sh"
    if ROS_MISSING
    else ""
)
