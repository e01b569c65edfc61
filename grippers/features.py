"""The optional features of a gripper (temperature, soft limits, the device tag), apart from the core of
:class:`~grippers.gripper.Gripper`: a device without the capability raises NotSupported and nothing is sent.

Each feature is an object the device offers (``Device.temperature``, ``.soft_limits``, ``.device_tag``) or
leaves None; the gripper's capabilities say which the user may call.
"""

from __future__ import annotations

from typing import Any

from .device import Device
from .errors import NotSupported
from .states import Capability


class Features:
    """The capability check and the feature object behind each optional method of a gripper."""

    def __init__(self, name: str, device: Device) -> None:
        self.name = name
        self.device = device
        self.capabilities = frozenset(device.capabilities)

    def require(self, capability: Capability, command: str) -> None:
        if capability not in self.capabilities:
            raise NotSupported(f"this device has no {capability.value}", device=self.name, command=command)

    def get(self, capability: Capability, command: str) -> Any:
        """The device's feature object for ``capability`` (NotSupported if it lacks either)."""
        self.require(capability, command)
        feature = getattr(self.device, capability.value, None)
        if feature is None:
            raise NotSupported(f"this device has no {capability.value}", device=self.name, command=command)
        return feature
