"""Every width, speed and force a user passes, checked against the limits in force before anything is sent.

A collaborator of :class:`~grippers.gripper.Gripper` (the checks are the same for every family and every
face: the threaded and asyncio calls, servo, and ``check()`` for a dry run); apart so the gripper holds the
behaviour of a gripper, not the arithmetic of its limits.
"""

from __future__ import annotations

from grippers.drivers.numbers import finite

from .errors import LimitError
from .profile_model import Limits, ProfileBase
from .units import to_m, to_mm


class ValueChecks:
    """Values in SI units against ``limits`` (the profile's, narrowed by the device's own); the defaults
    come from the profile. ``limits`` is replaced when a reconnected device reports others."""

    def __init__(self, name: str, profile: ProfileBase, limits: Limits) -> None:
        self.name = name
        self.profile = profile
        self.limits = limits

    def width(self, width: float, command: str) -> float:
        w = finite(width, "width", device=self.name, command=command)
        lo, hi = self.limits.min_width, self.limits.max_width
        if not lo - 1e-9 <= w <= hi + 1e-9:
            raise LimitError(
                f"width {to_mm(w):g} mm is outside {to_mm(lo):g}..{to_mm(hi):g} mm",
                device=self.name,
                command=command,
            )
        return min(max(w, lo), hi)

    def speed(self, speed: float | None, command: str) -> float:
        if speed is None:
            # The profile's default may lie above a safety limit or the device's own 53h limits (which narrow
            # the limits): sending it unchecked would bypass them, refusing it would break every call.
            default = to_m(self.profile.mechanics.default_speed_mm_s)
            return min(max(default, self.limits.min_speed), self.limits.max_speed)
        s = finite(speed, "speed", device=self.name, command=command)
        lo, hi = self.limits.min_speed, self.limits.max_speed
        if not lo - 1e-9 <= s <= hi + 1e-9 or s <= 0:
            raise LimitError(
                f"speed {to_mm(s):g} mm/s is outside {to_mm(lo):g}..{to_mm(hi):g} mm/s",
                device=self.name,
                command=command,
            )
        return min(max(s, lo), hi)

    def force(self, force: float | None, command: str) -> float:
        if force is None:
            default = self.profile.mechanics.default_force_n  # clamped for the reason given in speed()
            return min(max(default, self.limits.min_force), self.limits.max_force)
        f = finite(force, "force", device=self.name, command=command)
        lo, hi = self.limits.min_force, self.limits.max_force
        if not lo - 1e-9 <= f <= hi + 1e-9:
            raise LimitError(f"force {f:g} N is outside {lo:g}..{hi:g} N", device=self.name, command=command)
        return min(max(f, lo), hi)

    def soft_limits(self, min_width: float, max_width: float) -> tuple[float, float]:
        lo, hi = self.width(min_width, "set_soft_limits"), self.width(max_width, "set_soft_limits")
        if lo >= hi:
            raise LimitError("min_width must be below max_width", device=self.name, command="set_soft_limits")
        return lo, hi
