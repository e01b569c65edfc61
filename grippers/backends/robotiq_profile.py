"""The Robotiq family's profile model (docs/profiles.md, docs/protocols-robotiq.md §2), declared by the
backend as its ``profile_model``, and the unit's byte maps: the one place bytes become SI units and back.

The device speaks bytes (position, speed and force 0..255); the profile's ``robotiq`` section maps them to mm
(per unit: its own open and closed counts), mm/s and N (approximate: the grip force also depends on the
speed, the fingers and the part)."""

from __future__ import annotations

from typing import Annotated, Literal

from pydantic import BaseModel, ConfigDict, Field, model_validator

from grippers.drivers.robotiq.registers import BAUDRATE, DEFAULT_SLAVE, FORWARDER_PORT

from ..profiles import Baudrate, Length, ProfileBase, Timeout, TimeScale

FALLBACK_PROFILE = "robotiq-2f85"  # opened when no profile is named, and `grippers sim robotiq`'s default


class _Section(BaseModel):
    model_config = ConfigDict(extra="forbid", frozen=True)


Byte = Annotated[int, Field(ge=0, le=255)]


class RobotiqTransport(_Section):
    timeout_s: Timeout = 1.0
    slave: Annotated[int, Field(ge=1, le=247)] = DEFAULT_SLAVE
    baudrate: Baudrate = BAUDRATE
    tcp_port: Annotated[int, Field(ge=1, le=65535)] = FORWARDER_PORT
    read_function: Literal[3, 4] = 3  # READ_HOLDING, as the manuals and the SDK read the status


class RobotiqMaps(_Section):
    """The unit's byte maps. Positions: gPO of this unit fully open and fully closed (measured with nothing
    between the fingers: command rPR 0 and 255 and read gPO back), and the widths there. Speed and force:
    linear between the mechanics' minimum (byte 0) and maximum (byte 255); the force map is approximate."""

    open_count: Byte
    closed_count: Byte
    open_width_mm: Length
    closed_width_mm: Length = 0.0
    force_approximate: bool = True  # the grip force depends on speed, fingers and part, not only rFR
    grasp_travel_mm: Length = 10.0  # grasp() commands this far past the part's nominal width

    @model_validator(mode="after")
    def _ordered(self) -> RobotiqMaps:
        if self.open_count >= self.closed_count:
            raise ValueError("needs open_count < closed_count (gPO grows as the fingers close)")
        if self.open_width_mm <= self.closed_width_mm:
            raise ValueError("needs open_width_mm > closed_width_mm")
        return self


class RobotiqSimulator(_Section):
    activation_s: Annotated[float, Field(gt=0, le=60)] = 1.0
    part_width_mm: Length | None = None
    time_scale: TimeScale = 1.0
    watchdog_s: Annotated[float, Field(gt=0, le=60)] | None = None
    activated: bool = False  # start activated (a demo); the real gripper powers up not activated


class RobotiqProfile(ProfileBase):
    family: Literal["robotiq"] = "robotiq"
    transport: RobotiqTransport = RobotiqTransport()
    robotiq: RobotiqMaps
    simulator: RobotiqSimulator = RobotiqSimulator()

    @model_validator(mode="after")
    def _maps_fit_the_mechanics(self) -> RobotiqProfile:
        m, r = self.mechanics, self.robotiq
        if abs(m.min_width_mm - r.closed_width_mm) > 1e-6 or abs(m.max_width_mm - r.open_width_mm) > 1e-6:
            raise ValueError(
                f"robotiq: open_width_mm/closed_width_mm ({r.open_width_mm:g}/{r.closed_width_mm:g}) must be "
                f"the mechanics' max and min width ({m.max_width_mm:g}/{m.min_width_mm:g})"
            )
        return self

    # -- the byte maps (units change here and nowhere else) ------------------------------------------------

    def _count_per_mm(self) -> float:
        m = self.robotiq
        return (m.closed_count - m.open_count) / (m.open_width_mm - m.closed_width_mm)

    def position_byte(self, width: float) -> int:
        """rPR for ``width`` (m), by the unit's own open and closed counts."""
        m = self.robotiq
        return max(0, min(255, round(m.open_count + (m.open_width_mm - width * 1000) * self._count_per_mm())))

    def width_of(self, position: int) -> float:
        """The width (m) at gPO ``position``."""
        m = self.robotiq
        return (m.open_width_mm - (position - m.open_count) / self._count_per_mm()) / 1000

    @staticmethod
    def _scale(value: float, lo: float, hi: float) -> int:
        return 255 if hi <= lo else max(0, min(255, round((value - lo) / (hi - lo) * 255)))

    def speed_byte(self, speed: float) -> int:
        """rSP for ``speed`` (m/s): linear between the mechanics' minimum (0) and maximum (255)."""
        m = self.mechanics
        return self._scale(speed * 1000, m.min_speed_mm_s, m.max_speed_mm_s)

    def force_byte(self, force: float) -> int:
        """rFR for ``force`` (N): linear between the mechanics' minimum and maximum (approximate)."""
        m = self.mechanics
        return self._scale(force, m.min_force_n, m.max_force_n)
