"""The optional features of a gripper (temperature, soft limits, the device tag), apart from the core of
:class:`~grippers.gripper.Gripper`: a device without the capability raises NotSupported and nothing is sent.

A mixin of Gripper, so a backend overrides the same ``_temperature``/``_set_soft_limits``/``_device_tag``
hooks as before and users call the same methods on the gripper.
"""

from __future__ import annotations

from .errors import LimitError, NotSupported
from .limit_checks import LimitChecks
from .states import Capability


class OptionalFeatures(LimitChecks):
    """Features a family may lack; ``capabilities`` says which it has."""

    capabilities: frozenset[Capability] = frozenset()

    def require(self, capability: Capability, command: str) -> None:
        if capability not in self.capabilities:
            raise NotSupported(f"this device has no {capability.value}", device=self.name, command=command)

    def temperature(self) -> float:
        """The gripper's (or its driver's) temperature in °C."""
        self._check_open("temperature")
        self.require(Capability.TEMPERATURE, "temperature")
        return self._temperature()

    def set_soft_limits(self, min_width: float, max_width: float) -> None:
        """Limits the device itself enforces on finger motion (m)."""
        lo, hi = self._width(min_width, "set_soft_limits"), self._width(max_width, "set_soft_limits")
        if lo >= hi:
            raise LimitError("min_width must be below max_width", device=self.name, command="set_soft_limits")
        self._check_open("set_soft_limits")
        self.require(Capability.SOFT_LIMITS, "set_soft_limits")
        self._set_soft_limits(lo, hi)

    def clear_soft_limits(self) -> None:
        self._check_open("clear_soft_limits")
        self.require(Capability.SOFT_LIMITS, "clear_soft_limits")
        self._set_soft_limits(None, None)

    def device_tag(self) -> str:
        """The user-defined name stored in the device."""
        self._check_open("device_tag")
        self.require(Capability.DEVICE_TAG, "device_tag")
        return self._device_tag(None)

    def set_device_tag(self, tag: str) -> None:
        self._check_open("set_device_tag")
        self.require(Capability.DEVICE_TAG, "set_device_tag")
        self._device_tag(tag)

    # Backends override these when they declare the matching capability.
    def _temperature(self) -> float:
        raise NotSupported("not implemented by this backend", device=self.name, command="temperature")

    def _set_soft_limits(self, min_width: float | None, max_width: float | None) -> None:
        raise NotSupported("not implemented by this backend", device=self.name, command="set_soft_limits")

    def _device_tag(self, tag: str | None) -> str:
        raise NotSupported("not implemented by this backend", device=self.name, command="device_tag")
