"""What a gripper reports, the same for every family: its state, the outcome of a motion, what it is.

Plain frozen dataclasses and enums, apart from the :class:`~grippers.gripper.Gripper` that produces them, so
the remote face, the CLI and a backend can use them without the machinery of the generic gripper.
"""

from __future__ import annotations

import enum
from dataclasses import dataclass, field
from typing import Any, Literal

from .profile_model import Limits

__all__ = ["Capability", "DeviceInfo", "GraspResult", "GraspState", "GripperState", "MotionResult"]


class GraspState(enum.Enum):
    """One grasp state for every family (WSG grasping states; MSG object detection mapped onto them)."""

    IDLE = "idle"
    POSITIONING = "positioning"
    GRASPING = "grasping"
    HOLDING = "holding"
    NO_PART = "no_part"
    PART_LOST = "part_lost"
    RELEASING = "releasing"
    ERROR = "error"


# The names of GraspState as JSON documents carry them (CLI --json, the remote key space); a test keeps the
# two in step (tests/api/test_states.py), so the schemas need no computed Literal.
GraspName = Literal[
    "idle", "positioning", "grasping", "holding", "no_part", "part_lost", "releasing", "error"
]


class Capability(enum.Enum):
    """Optional features a backend declares; a call needing one the device lacks raises NotSupported."""

    FORCE_CONTROL = "force_control"  # grasp force set in newtons on the device
    CURRENT_CONTROL = "current_control"  # force estimated from a motor current limit
    SOFT_LIMITS = "soft_limits"
    TEMPERATURE = "temperature"
    DEVICE_TAG = "device_tag"
    FINGER_DATA = "finger_data"
    CALIBRATION = "calibration"  # home() calibrates the stroke (MSG)
    HOMING = "homing"  # home() references the axis (WSG)
    FORCE_MEASUREMENT = "force_measurement"  # state().force is measured
    PUSH_UPDATES = "push_updates"  # the device streams state by itself


@dataclass(frozen=True, slots=True)
class GripperState:
    """A snapshot in SI units. ``force`` is None where the device reports only ``current`` (A)."""

    width: float
    speed: float | None
    force: float | None
    current: float | None
    grasp: GraspState
    moving: bool
    referenced: bool
    faults: tuple[str, ...]
    timestamp: float  # time.time() when the snapshot was taken
    gap: bool = False  # the first state after a reconnection: states were missed before it (reconnect=true)

    @property
    def fast_stopped(self) -> bool:
        """Whether the device is in FAST STOP (``acknowledge()`` clears it)."""
        return "fast_stop" in self.faults


@dataclass(frozen=True, slots=True)
class MotionResult:
    width: float
    state: GraspState


@dataclass(frozen=True, slots=True)
class GraspResult:
    """``grasped`` tells whether a part is held; ``reason`` says why not when it is not."""

    grasped: bool
    width: float
    force: float | None
    state: GraspState
    reason: str | None = None


@dataclass(frozen=True)
class DeviceInfo:
    family: str
    vendor: str
    model: str
    serial: str | None
    firmware: str | None
    hardware: str | None
    limits: Limits
    url: str
    profile: str
    extra: dict[str, Any] = field(default_factory=dict)

    @property
    def stroke(self) -> float:
        """The usable travel in m (the limits' max minus min width)."""
        return self.limits.stroke
