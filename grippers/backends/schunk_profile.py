"""The SCHUNK family's profile model (docs/profiles.md, docs/protocols-schunk.md): the ``[schunk]`` section
(how to reach the unit, and what the simulator reports as the unit's parameters).

Widths are the distance between the jaws (the total, not per jaw): SCHUNK's parameters say so (an EGU 60's
``max_pos`` and ``max_phys_stroke`` are 120 mm, an EGK 25's 53 mm; per jaw they would be 60 and 26.5 mm, the
datasheets' "stroke per jaw"), and it is the one convention of every family here. The limits the gripper
enforces come from the unit's own parameters read at open; the profile's mechanics are the fallback and the
simulator's values.
"""

from __future__ import annotations

from typing import Annotated, Literal

from pydantic import BaseModel, ConfigDict, Field

from grippers.drivers.schunk.protocol import (
    DEFAULT_DEVICE_ID,
    DEFAULT_HTTP_PORT,
    MODBUS_BAUDRATE,
    MODULE_TYPES,
)

from ..profiles import Length, ProfileBase, Timeout, TimeScale

FALLBACK_PROFILE = "schunk-egu-60"  # opened when no profile is named, and `grippers sim schunk`'s default


class _Section(BaseModel):
    model_config = ConfigDict(extra="forbid", frozen=True)


class SchunkSection(_Section):
    module_type: Annotated[int, Field(ge=min(MODULE_TYPES), le=max(MODULE_TYPES))]  # 0x0500 of this model
    max_grip_speed_mm_s: Annotated[float, Field(gt=0)]  # 0x0650
    release_delta_mm: Length = 5.0  # 0x0540: how far release() opens first
    http_port: Annotated[int, Field(ge=1, le=65535)] = DEFAULT_HTTP_PORT
    device_id: Annotated[int, Field(ge=1, le=247)] = DEFAULT_DEVICE_ID
    baudrate: Annotated[int, Field(gt=0)] = MODBUS_BAUDRATE
    timeout_s: Timeout = 1.0  # SCHUNK's driver: httpx Client(timeout=1.0)
    gpe: bool = False  # grip force and position maintenance on grasp() (M modules only)


class SchunkSimulator(_Section):
    fieldbus: Literal["PN", "EI", "EC", "MB"] = "EI"  # the byte order the simulated unit answers in
    part_width_mm: Length | None = None
    time_scale: TimeScale = 1.0
    serial: str = "SIM00001"
    firmware: str = "5.3.0.90971"


class SchunkProfile(ProfileBase):
    family: Literal["schunk"] = "schunk"
    schunk: SchunkSection
    simulator: SchunkSimulator = SchunkSimulator()

    @property
    def module_name(self) -> str:
        return MODULE_TYPES[self.schunk.module_type]
