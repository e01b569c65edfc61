"""The ROS 2 face of a :class:`~grippers.Gripper` (``grippers ros2 URL``; docs/ros2.md).

rclpy and the message packages are not dependencies of grippers: they come from the user's ROS 2 installation
(``source /opt/ros/jazzy/setup.bash``), so nothing here imports them at module level. :func:`load_ros` imports
them when the node starts and names what is missing otherwise.
"""

from __future__ import annotations

import importlib
from types import ModuleType

from ..errors import NotSupported

__all__ = ["RosUnavailable", "load_ros"]

# (module, the ROS package that provides it)
_NEEDED = (
    ("rclpy", "rclpy"),
    ("rclpy.action", "rclpy"),
    ("sensor_msgs.msg", "sensor_msgs"),
    ("std_srvs.srv", "std_srvs"),
    ("diagnostic_msgs.msg", "diagnostic_msgs"),
    ("control_msgs.action", "control_msgs (ros-jazzy-control-msgs)"),
)


class RosUnavailable(NotSupported):
    """rclpy or a message package the node needs cannot be imported."""


def load_ros() -> dict[str, ModuleType]:
    """Import what the node needs; RosUnavailable names every missing package and how to get it."""
    loaded: dict[str, ModuleType] = {}
    missing: list[str] = []
    for module, package in _NEEDED:
        if any(m.startswith(package + " ") for m in missing):
            continue  # rclpy.action when rclpy itself is missing: said once
        try:
            loaded[module] = importlib.import_module(module)
        except ImportError as exc:
            missing.append(f"{package} ({exc})")
    if missing:
        raise RosUnavailable(
            "ROS 2 is not available to this Python: missing "
            + "; ".join(missing)
            + ". rclpy and the message packages come from a ROS 2 installation, not from pip: source it "
            "(e.g. `source /opt/ros/jazzy/setup.bash`, with ros-jazzy-control-msgs installed) and run again "
            "with the Python it was built for (docs/ros2.md)",
            command="ros2",
        )
    return loaded
