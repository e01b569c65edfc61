"""The MSG-on-STEPFOC family's profile model: its transport defaults, the byte/current maps and simulator
settings (docs/profiles.md), declared by the backend as its ``profile_model``."""

from __future__ import annotations

from typing import Annotated, Any, Literal

from pydantic import Field, model_validator

from ..profiles import MAX_FORCE_N, Baudrate, Length, ProfileBase, Timeout, TimeScale, _Model

MAX_NODE = 15  # 4-bit node id (MSG manual, "Bits 10 - 7 of CAN ID"; docs/protocols.md §2)


class StepfocTransport(_Model):
    timeout_s: Timeout = 0.5
    baudrate: Baudrate = 256_000  # docs/protocols.md §2 UART
    can_interface: str = "socketcan"
    can_channel: str = "can0"
    can_bitrate: Annotated[int, Field(gt=0)] = 1_000_000  # docs/protocols.md §2 CAN
    node: Annotated[int, Field(ge=0, le=MAX_NODE)] = 0


class MsgMaps(_Model):
    """How the driver's raw bytes and milliamps relate to width, speed and force.

    Position: byte 0 is fully open, 255 fully closed, linear between the calibrated end stops
    (docs/protocols.md §2). Speed: byte 0..255 maps linearly to about 500..60000 encoder ticks/s; the mm/s at
    both ends depend on the rail's gearing and are estimates to calibrate per unit. Force: the MSG has no
    force sensor; force is estimated from the current limit.
    """

    open_width_mm: Length
    closed_width_mm: Length = 0.0
    # The one speed model (drivers/stepfoc/speed.py): the driver's firmware maps the speed byte to ticks/s,
    # ticks_per_mm (from the calibrated stops) makes it mm/s. speed_at_* are derived from them (properties,
    # so a profile that extends another with another driver gets its own); given by hand they must agree,
    # or a requested speed would not be the speed the jaws move (issue 19).
    driver: Literal["stepfoc", "spectral-micro"] = "stepfoc"
    ticks_per_mm: Annotated[float, Field(gt=0, le=1e6, allow_inf_nan=False)] = 200.0
    newton_per_amp: Annotated[float, Field(gt=0, le=MAX_FORCE_N, allow_inf_nan=False)]
    min_current_ma: Annotated[int, Field(ge=0)] = 150  # below about 150 mA the motion is unstable (MSG doc)
    max_current_ma: Annotated[int, Field(gt=0, le=2800)] = 1000  # MSG doc: 0-1000 mA
    default_current_ma: Annotated[int, Field(gt=0)] = 500
    grasp_travel_mm: Length = 10.0  # a grasp commands this far inside the nominal width
    inside_grip: bool = False  # a part gripped from inside (object detected while opening)

    @model_validator(mode="before")
    @classmethod
    def _speeds_from_the_driver(cls, data: Any) -> Any:
        if not isinstance(data, dict):
            return data
        from grippers.drivers.stepfoc.speed import speed_mm_s, variant

        try:
            driver = variant(str(data.get("driver", "stepfoc")))
            tpm = float(data.get("ticks_per_mm", 200.0))
        except (TypeError, ValueError):
            return data  # the field validators name the problem
        if not tpm > 0:
            return data
        derived = {
            "speed_at_0_mm_s": speed_mm_s(0, tpm, driver),
            "speed_at_255_mm_s": speed_mm_s(255, tpm, driver),
        }
        out = dict(data)
        for key, value in derived.items():
            given = out.pop(key, None)
            if given is None:
                continue
            if not isinstance(given, int | float) or abs(float(given) - value) > 0.01 * value:
                raise ValueError(
                    f"{key} = {given!r} disagrees with the {driver.name} speed map at {tpm:g} ticks/mm "
                    f"({value:g} mm/s): set maps.ticks_per_mm (calibrated stops / stroke) instead"
                )
        return out

    @property
    def speed_at_0_mm_s(self) -> float:
        """Jaw speed of speed byte 0 (mm/s), from the driver's speed map and ticks_per_mm."""
        from grippers.drivers.stepfoc.speed import speed_mm_s, variant

        return speed_mm_s(0, self.ticks_per_mm, variant(self.driver))

    @property
    def speed_at_255_mm_s(self) -> float:
        """Jaw speed of speed byte 255 (mm/s)."""
        from grippers.drivers.stepfoc.speed import speed_mm_s, variant

        return speed_mm_s(255, self.ticks_per_mm, variant(self.driver))

    @model_validator(mode="after")
    def _ordered(self) -> MsgMaps:
        if self.open_width_mm <= self.closed_width_mm:
            raise ValueError("needs open_width_mm > closed_width_mm")
        if not self.min_current_ma <= self.default_current_ma <= self.max_current_ma:
            raise ValueError("needs min_current_ma <= default_current_ma <= max_current_ma")
        return self


class MsgSimulator(_Model):
    part_width_mm: Length | None = None
    hardware_version: Annotated[int, Field(ge=0, le=255)] = 1
    software_version: Annotated[int, Field(ge=0, le=255)] = 1
    serial: Annotated[int, Field(ge=0, le=0xFFFFFFFF)] = 1001
    time_scale: TimeScale = 1.0


class MsgProfile(ProfileBase):
    family: Literal["stepfoc"] = "stepfoc"
    transport: StepfocTransport = StepfocTransport()
    maps: MsgMaps
    simulator: MsgSimulator = MsgSimulator()

    @model_validator(mode="after")
    def _maps_fit_the_mechanics(self) -> MsgProfile:
        m, maps = self.mechanics, self.maps
        # Position bytes 0..255 span closed..open (docs/protocols.md §2): a map narrower than the stroke
        # would clamp every byte at its end and silently end moves early.
        if maps.closed_width_mm > m.min_width_mm + 1e-9 or maps.open_width_mm < m.max_width_mm - 1e-9:
            raise ValueError(
                f"maps: closed_width_mm..open_width_mm ({maps.closed_width_mm:g}..{maps.open_width_mm:g} mm) "
                f"must cover the stroke ({m.min_width_mm:g}..{m.max_width_mm:g} mm), or moves end early"
            )
        # The speed limits must be speeds the driver can run (bytes 0..255 of the one speed model).
        if (
            m.min_speed_mm_s < maps.speed_at_0_mm_s * 0.999
            or m.max_speed_mm_s > maps.speed_at_255_mm_s * 1.001
        ):
            raise ValueError(
                f"mechanics speeds {m.min_speed_mm_s:g}..{m.max_speed_mm_s:g} mm/s must lie within what the "
                f"driver runs ({maps.speed_at_0_mm_s:g}..{maps.speed_at_255_mm_s:g} mm/s at "
                f"{maps.ticks_per_mm:g} ticks/mm)"
            )
        # The force is estimated from the current limit: the currents the driver may use must give a force
        # inside the mechanics' range, or every grasp is refused.
        npa, low_ma, high_ma = maps.newton_per_amp, maps.min_current_ma, self.effective_max_current_ma
        if max(m.min_force_n, low_ma / 1000 * npa) > min(m.max_force_n, high_ma / 1000 * npa):
            raise ValueError(
                f"maps.newton_per_amp: {npa:g} N/A over {low_ma}..{high_ma} mA gives "
                f"{low_ma / 1000 * npa:g}..{high_ma / 1000 * npa:g} N, outside mechanics' "
                f"{m.min_force_n:g}..{m.max_force_n:g} N: no grasp force would be possible"
            )
        return self

    @property
    def effective_max_current_ma(self) -> int:
        limit = self.maps.max_current_ma
        if self.safety.max_current_ma is not None:
            limit = min(limit, self.safety.max_current_ma)
        return limit
