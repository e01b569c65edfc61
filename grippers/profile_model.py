"""The profile model: the pydantic classes a profile file is validated with, and their bounds.

Pure data, no search path: :mod:`grippers.profiles` loads files into these models (and asks the backends which
subclass a family uses), while the Gripper core, the states and every backend's own profile model build on the
classes here. Split from profiles.py so the core does not import the loader, which imports the backend table,
which names the Gripper (issue 32: no import circles). ``grippers.profiles`` re-exports every name.
"""

from __future__ import annotations

import re
from typing import Annotated

from pydantic import BaseModel, ConfigDict, Field, model_validator

from .settings import RANGES
from .timeouts import MAX_TIMEOUT_S
from .units import to_amps, to_m

# Every number is finite and below a bound no real gripper comes near: beyond them a profile cannot work
# (an infinite stroke makes home() wait for ever, an opening width of 1e308 overflows in state(), a WSG stroke
# of 1e308 kills the simulator's thread), so they are refused at load, naming the field and the rule.
MAX_LENGTH_MM = 10_000.0  # 10 m
MAX_SPEED_MM_S = 100_000.0  # 100 m/s
MAX_ACCEL_MM_S2 = 10_000_000.0
MAX_FORCE_N = 100_000.0
MAX_TIME_SCALE = 1_000_000.0

NonNegative = Annotated[float, Field(ge=0, allow_inf_nan=False)]
Positive = Annotated[float, Field(gt=0, allow_inf_nan=False)]
Length = Annotated[float, Field(ge=0, le=MAX_LENGTH_MM, allow_inf_nan=False)]
PositiveLength = Annotated[float, Field(gt=0, le=MAX_LENGTH_MM, allow_inf_nan=False)]
Speed = Annotated[float, Field(ge=0, le=MAX_SPEED_MM_S, allow_inf_nan=False)]
PositiveSpeed = Annotated[float, Field(gt=0, le=MAX_SPEED_MM_S, allow_inf_nan=False)]
Accel = Annotated[float, Field(ge=0, le=MAX_ACCEL_MM_S2, allow_inf_nan=False)]
PositiveAccel = Annotated[float, Field(gt=0, le=MAX_ACCEL_MM_S2, allow_inf_nan=False)]
Force = Annotated[float, Field(ge=0, le=MAX_FORCE_N, allow_inf_nan=False)]
PositiveForce = Annotated[float, Field(gt=0, le=MAX_FORCE_N, allow_inf_nan=False)]
Timeout = Annotated[float, Field(gt=0, le=MAX_TIMEOUT_S, allow_inf_nan=False)]
TimeScale = Annotated[float, Field(gt=0, le=MAX_TIME_SCALE, allow_inf_nan=False)]
Port = Annotated[int, Field(ge=1, le=65535)]
CanId = Annotated[int, Field(ge=0, le=0x7FF)]  # standard 11-bit identifiers
# A serial link's baud rate, bounded as the URL's ?baudrate= is (grippers/settings.py RANGES: one rule):
# ``baudrate = 1e20`` passed ``profiles validate`` and open() then raised OverflowError (issue 43 §5).
Baudrate = Annotated[int, Field(ge=int(RANGES["baudrate"][0]), le=int(RANGES["baudrate"][1]))]


class _Model(BaseModel):
    # Unknown keys are refused so a typo in a profile is an error, not a silently ignored setting.
    model_config = ConfigDict(extra="forbid", frozen=True)


class Mechanics(_Model):
    """The mechanism's own range (datasheet or device), in mm, mm/s, mm/s² and N."""

    stroke_mm: PositiveLength
    min_width_mm: Length = 0.0
    min_speed_mm_s: Speed
    max_speed_mm_s: PositiveSpeed
    default_speed_mm_s: PositiveSpeed
    min_accel_mm_s2: Accel | None = None
    max_accel_mm_s2: PositiveAccel | None = None
    min_force_n: Force
    max_force_n: PositiveForce
    default_force_n: PositiveForce

    @property
    def max_width_mm(self) -> float:
        return self.min_width_mm + self.stroke_mm

    @model_validator(mode="after")
    def _ordered(self) -> Mechanics:
        if not self.min_speed_mm_s <= self.default_speed_mm_s <= self.max_speed_mm_s:
            raise ValueError("needs min_speed_mm_s <= default_speed_mm_s <= max_speed_mm_s")
        if not self.min_force_n <= self.default_force_n <= self.max_force_n:
            raise ValueError("needs min_force_n <= default_force_n <= max_force_n")
        if (
            self.min_accel_mm_s2 is not None
            and self.max_accel_mm_s2 is not None
            and self.min_accel_mm_s2 > self.max_accel_mm_s2
        ):
            raise ValueError("needs min_accel_mm_s2 <= max_accel_mm_s2")
        return self


class Safety(_Model):
    """Limits the library enforces below the mechanism's own: beyond them, refused before sending."""

    max_force_n: PositiveForce | None = None
    max_speed_mm_s: PositiveSpeed | None = None
    min_width_mm: Length | None = None
    max_width_mm: PositiveLength | None = None
    max_current_ma: Annotated[int, Field(gt=0, le=2800)] | None = None  # MSG: the driver can push 2800 mA

    @model_validator(mode="after")
    def _ordered(self) -> Safety:
        lo, hi = self.min_width_mm, self.max_width_mm
        if lo is not None and hi is not None and lo >= hi:
            raise ValueError("needs min_width_mm < max_width_mm (no width would be allowed)")
        return self


class Limits(_Model):
    """The effective limits (mechanics narrowed by safety) in SI units: what the API checks against."""

    min_width: float
    max_width: float
    min_speed: float
    max_speed: float
    min_force: float
    max_force: float
    max_current: float | None = None  # A, devices that control current instead of force

    @property
    def stroke(self) -> float:
        """The usable travel in m: max_width - min_width."""
        return self.max_width - self.min_width


class Connection(_Model):
    """Automatic reconnection (grippers/reconnect.py); URL parameters and keywords of the same names win."""

    reconnect: bool = False
    # Bounded like a timeout: a backoff of 1e308 s overflows the condition wait of the reconnection thread.
    reconnect_backoff_s: Timeout = 0.1  # first retry after this, doubling up to the maximum
    reconnect_backoff_max_s: Timeout = 5.0
    heartbeat_s: Timeout = 0.5  # a state query this often notices a link that died while idle
    acknowledge_on_reconnect: bool = False  # a safety decision: off unless the application says so


class ProfileBase(_Model):
    """A device profile (docs/profiles.md): the model's mechanics, safety limits and connection defaults.

    Read from TOML, YAML or JSON by :func:`load_profile`; each family's backend declares a subclass with its
    own sections (its ``profile_model``: ``WsgProfile``, ``MsgProfile``, ``RobotiqProfile``). Validation
    errors name the file, the field and the rule (``ProfileError``).
    """

    name: Annotated[str, Field(pattern=r"^[a-z0-9][a-z0-9._-]*$")]
    family: str
    vendor: str
    model: str
    aliases: list[str] = []
    description: str = ""
    source: str = ""  # where the numbers come from
    url: str  # default connection URL
    mechanics: Mechanics
    safety: Safety = Safety()
    connection: Connection = Connection()
    path: Annotated[str | None, Field(exclude=True)] = None  # the file it was read from
    # The profile this one was built on (docs/profiles.md "extends"); resolved at load, not part of a dump.
    extends: Annotated[str | None, Field(exclude=True)] = None

    @model_validator(mode="after")
    def _safety_leaves_a_range(self) -> ProfileBase:
        """Safety limits narrow the mechanics; narrowed to nothing, every command would be refused."""
        m, s = self.mechanics, self.safety
        lo = max(m.min_width_mm, s.min_width_mm or 0.0)
        hi = min(m.max_width_mm, s.max_width_mm if s.max_width_mm is not None else m.max_width_mm)
        if lo >= hi:
            raise ValueError(
                f"safety: the allowed widths {lo:g}..{hi:g} mm are empty (mechanics: {m.min_width_mm:g}.."
                f"{m.max_width_mm:g} mm); needs safety.min_width_mm < safety.max_width_mm within the stroke"
            )
        if s.max_speed_mm_s is not None and s.max_speed_mm_s < m.min_speed_mm_s:
            raise ValueError(
                f"safety.max_speed_mm_s: {s.max_speed_mm_s:g} is below mechanics.min_speed_mm_s "
                f"{m.min_speed_mm_s:g} (no speed would be allowed)"
            )
        if s.max_force_n is not None and s.max_force_n < m.min_force_n:
            raise ValueError(
                f"safety.max_force_n: {s.max_force_n:g} is below mechanics.min_force_n {m.min_force_n:g} "
                "(no grasp force would be allowed)"
            )
        return self

    def limits(self) -> Limits:
        """The limits the library enforces (SI units): the mechanics narrowed by the safety section."""
        m, s = self.mechanics, self.safety
        max_current = getattr(self, "effective_max_current_ma", None)
        return Limits(
            min_width=to_m(max(m.min_width_mm, s.min_width_mm or 0.0)),
            max_width=to_m(min(m.max_width_mm, s.max_width_mm or m.max_width_mm)),
            min_speed=to_m(m.min_speed_mm_s),
            max_speed=to_m(min(m.max_speed_mm_s, s.max_speed_mm_s or m.max_speed_mm_s)),
            min_force=m.min_force_n,
            max_force=min(m.max_force_n, s.max_force_n or m.max_force_n),
            max_current=to_amps(max_current),
        )

    def matches(self, name: str) -> bool:
        """Whether ``name`` is this profile's name or one of its aliases (case, spaces and dashes ignored)."""
        key = _key(name)
        return key == _key(self.name) or any(key == _key(a) for a in self.aliases)


def _key(name: str) -> str:
    return re.sub(r"[^a-z0-9]", "", name.lower())
