"""``DeviceGripper``: an alias of :class:`~grippers.gripper.Gripper`, kept for plugins and docs that name it.

The gripper holding a :class:`~grippers.device.Device` used to be a subclass of its own; since the device
contract replaced the backend hooks, :class:`~grippers.gripper.Gripper` itself holds the device, and
``DeviceGripper(device, profile, url, timeout=...)`` is the same call as ``Gripper(...)``.
"""

from __future__ import annotations

from .fast_stop import FAST_STOP_FAULT
from .gripper import Gripper

DeviceGripper = Gripper
"""An alias of :class:`~grippers.gripper.Gripper` (the one public class that holds a device)."""

__all__ = ["FAST_STOP_FAULT", "DeviceGripper"]
