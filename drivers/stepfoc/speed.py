"""The ONE speed and position model of the MSG drivers, shared by the simulator, the profiles and the backend.

Why one module: a profile whose speed map disagrees with the simulator (or the device) makes
``max_speed_mm_s`` meaningless (issue 19: 5 mm/s ran at 14 mm/s). Everything that turns a speed byte into a
jaw speed, or a width into encoder ticks, comes from here and from firmware facts only:

* ``Gripper_mode`` maps the speed byte with Arduino ``map(speed, 0, 255, min_speed, max_speed)`` (integer
  arithmetic, C truncation) to encoder ticks per second. STEPFOC firmware ``src/common.h``:
  ``min_speed = 500``, ``max_speed = 60000``; Spectral Micro firmware ``src/common.h``: ``min_speed = 40``,
  ``max_speed = 80000``.
* Ticks per millimetre of jaw opening follow from the calibrated stops: ``(max_open_position -
  max_closed_position) / stroke``. The firmware's values before calibration are 10329 and -229
  (both firmwares' ``common.h``). A unit's own figure is read from ``#Gripinfo``
  (max open / closed position) after ``home()``.
* Control loop: ``LOOP_FREQ`` 6250 Hz on STEPFOC (160 us per tick), 5000 Hz on Spectral Micro
  (``constants.h``).
* Calibration (``Calibrate_gripper``): current limit 600 mA and speed byte 20 on STEPFOC, 500 mA and speed 40
  with 3200 confirming ticks at each stop on Spectral Micro (commit 53ac915); 100 ticks of pause at the open
  stop; time-out after 150,000 ticks spent in calibration.
* Spectral Micro's action-0 branch of ``Gripper_mode`` pulls the bridge's SLEEP and RESET pins low: a stop
  there switches the motor off and releases the part.
"""

from __future__ import annotations

from dataclasses import dataclass

__all__ = [
    "DEFAULT_CLOSED_TICKS",
    "DEFAULT_OPEN_TICKS",
    "SPECTRAL_MICRO",
    "STEPFOC",
    "VARIANTS",
    "DriverVariant",
    "arduino_map",
    "speed_byte_for",
    "speed_mm_s",
    "ticks_per_s",
    "variant",
]

DEFAULT_OPEN_TICKS = 10329  # Gripper.max_open_position before calibration (common.h, both firmwares)
DEFAULT_CLOSED_TICKS = -229  # Gripper.max_closed_position before calibration
DEFAULT_TICKS_PER_MM = 200.0  # estimate: 10558 ticks between the default stops over an MSG 100's 55 mm is 192


@dataclass(frozen=True, slots=True)
class DriverVariant:
    """The firmware constants that differ between the two drivers the MSG is sold with."""

    name: str
    loop_hz: int
    min_speed_ticks: int
    max_speed_ticks: int
    calibration_current_ma: int
    calibration_speed: int  # a speed byte, mapped like a command's
    calibration_confirm_ticks: int  # ticks the stop must be held before it is recorded (0: at once)
    calibration_pause_ticks: int = 100
    calibration_timeout_ticks: int = 150_000
    stop_releases: bool = False  # action 0 switches the bridge off (the part is let go)

    @property
    def tick_s(self) -> float:
        return 1.0 / self.loop_hz

    @property
    def calibration_timeout_s(self) -> float:
        return self.calibration_timeout_ticks / self.loop_hz


STEPFOC = DriverVariant("stepfoc", 6250, 500, 60000, 600, 20, 0)
SPECTRAL_MICRO = DriverVariant("spectral-micro", 5000, 40, 80000, 500, 40, 3200, stop_releases=True)
VARIANTS = {v.name: v for v in (STEPFOC, SPECTRAL_MICRO)}


def variant(name: str) -> DriverVariant:
    try:
        return VARIANTS[name]
    except KeyError:
        raise ValueError(f"unknown MSG driver {name!r} (known: {', '.join(VARIANTS)})") from None


def _cdiv(a: int, b: int) -> int:
    """C integer division (truncates towards zero), as the firmware's ``map`` does."""
    q = abs(a) // abs(b)
    return q if (a >= 0) == (b >= 0) else -q


def arduino_map(x: int, in_min: int, in_max: int, out_min: int, out_max: int) -> int:
    """Arduino ``map`` on ints: ``(x - in_min) * (out_max - out_min) / (in_max - in_min) + out_min``."""
    if in_max == in_min:
        return out_min
    return _cdiv((x - in_min) * (out_max - out_min), in_max - in_min) + out_min


def ticks_per_s(speed: int, driver: DriverVariant = STEPFOC) -> int:
    """Encoder ticks per second the firmware commands for a speed byte."""
    return arduino_map(speed, 0, 255, driver.min_speed_ticks, driver.max_speed_ticks)


def speed_mm_s(speed: int, ticks_per_mm: float, driver: DriverVariant = STEPFOC) -> float:
    """Jaw speed in mm/s for a speed byte."""
    return ticks_per_s(speed, driver) / ticks_per_mm


def speed_byte_for(mm_s: float, ticks_per_mm: float, driver: DriverVariant = STEPFOC) -> int:
    """The fastest speed byte whose speed does not exceed ``mm_s`` (0 when even byte 0 is faster): a profile's
    speed limit then holds on the device."""
    want = mm_s * ticks_per_mm
    lo, hi = 0, 255
    if ticks_per_s(0, driver) > want:
        return 0
    while lo < hi:  # ticks_per_s is monotonic in the byte
        mid = (lo + hi + 1) // 2
        if ticks_per_s(mid, driver) <= want + 1e-9:
            lo = mid
        else:
            hi = mid - 1
    return lo
