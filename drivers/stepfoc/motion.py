"""Sans-IO trackers that read the end of a motion or a calibration from successive MSG status readings.

Why here and not in the backend: the rules come from the firmware (docs/protocols.md §2, "Firmware timing and
state a client must survive") and must be the same for every face (CAN, UART, the threaded backend, tests).
They take readings and the caller's monotonic time and return a verdict; they send nothing and sleep never.

Facts they rest on (STEPFOC firmware ``src/motor_control.cpp``, ``Gripper_mode`` / ``Calibrate_gripper``):

* detection 3 is a latch: a byte-identical 61, or a poll racing a new one, leaves it set while the jaws still
  travel, so 3 counts as "arrived" only with the jaws at the target byte;
* detection 1/2 needs ``|Iq| > 0.8 * limit`` with the velocity below 500 ticks/s. At motion start the first
  current request (about 360 mA at speed 255) can flag it before the jaws moved: a flag with the jaws still
  where they started is believed only once it has lasted :data:`CONFIRM_S`;
* blocked by a part at low speed the current needs about 2.5 s to reach 800 mA, so the flag comes late: jaws
  standing still with the current well above the idle reading are "pushing", waited for up to
  :func:`ramp_bound_s`; jaws standing still with an idle current were stopped (idled, cleared) elsewhere;
* the current reading is noisy and offset by tens of mA (``Get_current_mA``, no offset calibration): every
  current threshold sits above :data:`IDLE_CURRENT_MA`;
* a recalibration keeps the calibrated bit set; its last 2 % of travel already reads position >= 250 with a
  small current, and the current then ramps at the stop for about 60 ms (longer on Spectral Micro): its end is
  the jaws at rest at the closed stop, current low, for :data:`CAL_REST_S`;
* a calibration that reaches its 150,000-tick time-out drops (or leaves) the calibrated bit at 0 and idles;
  an aborted one leaves its step state half set and resumes at the next 62, so a client retries once.
"""

from __future__ import annotations

from dataclasses import dataclass
from enum import Enum

__all__ = [
    "CAL_REST_S",
    "CONFIRM_S",
    "IDLE_CURRENT_MA",
    "STALL_MIN_S",
    "CalibrationTracker",
    "MotionTracker",
    "Reading",
    "Verdict",
    "ramp_bound_s",
]

IDLE_CURRENT_MA = 80  # above the largest idle reading (offset tens of mA plus noise)
CONFIRM_S = 0.05  # an object flag with the jaws not yet moved must last this long (start-up lasts ms)
CAL_REST_S = 0.25  # closed stop, low current, this long: the calibration has ended (ramps last < 0.1 s)
FIRST_REST_S = 1.0  # the same before the first calibration, at an idle current (see CalibrationTracker)
CAL_CLOSED_BYTE = 254  # the calibrated closed stop reads 255; allow one byte of truncation
CAL_IDLE_CURRENT_MA = 300  # half the calibration current: no longer pushing on the stop
RAMP_MA_PER_S_AT_0 = 800.0 / 2.5  # blocked current rise at speed byte 0 (the slowest)
ARRIVED_BYTES = 2  # detection 3 with the jaws this close to the target byte: arrived
# A motion that reports "moving" while the jaws stand still has ended without its target: the driver was idled
# (clear error, idle, watchdog from elsewhere; the 60 frame cannot show the driver mode) or it pushes below
# the firmware's contact current. The least stall_s a caller gives MotionTracker (a slow motion: more).
STALL_MIN_S = 0.5


def ramp_bound_s(limit_ma: int) -> float:
    """Longest wait for a blocked motion's current to pass 80 % of ``limit_ma`` (at speed byte 0), with a
    margin of half again: a slow grasp's late detection is waited for this long, no longer."""
    return 1.5 * 0.8 * abs(limit_ma) / RAMP_MA_PER_S_AT_0 + 0.5


@dataclass(frozen=True, slots=True)
class Reading:
    """What a status poll says, in device units (``current_ma`` None: the UART does not report it)."""

    position: int
    detection: int
    calibrated: bool
    current_ma: int | None = None


class Verdict(Enum):
    RUNNING = "running"
    ARRIVED = "arrived"  # detection 3 at the target
    OBJECT = "object"  # detection 1 or 2, believed
    STALLED = "stalled"  # the jaws stopped without either: stopped elsewhere (idle, clear error) or stuck
    ENDED = "ended"  # calibration ended
    RETRY = "retry"  # calibration ended without success (time-out, never ran): send 62 once more


class MotionTracker:
    """One motion from the command to its end. ``stall_s``: how long the jaws may stand still with an idle
    current before the motion counts as stopped elsewhere; ``limit_ma``: the command's current limit."""

    def __init__(self, start: int | None, target: int, now: float, *, stall_s: float, limit_ma: int) -> None:
        self.start = start  # None: the first reading's position
        self.target = target
        self.stall_s = stall_s
        self.push_bound_s = ramp_bound_s(limit_ma)
        self.moved = False
        self._flag_since: float | None = None
        self._last_position = start
        self._still_since = now

    def update(self, r: Reading, now: float) -> Verdict:
        if self.start is None:
            self.start = self._last_position = r.position
            self._still_since = now
        if r.position != self._last_position:
            self._last_position, self._still_since = r.position, now
        if r.position != self.start:
            self.moved = True
        if r.detection == 3:
            self._flag_since = None
            if abs(r.position - self.target) <= ARRIVED_BYTES:
                return Verdict.ARRIVED
        elif r.detection in (1, 2):
            if self._flag_since is None:
                self._flag_since = now
            if self.moved or now - self._flag_since >= CONFIRM_S:
                return Verdict.OBJECT
            return Verdict.RUNNING
        else:
            self._flag_since = None
        still = now - self._still_since
        pushing = r.current_ma is None or abs(r.current_ma) > IDLE_CURRENT_MA
        if pushing:
            # the current may still be rising towards the contact threshold (or, on the UART, unknown)
            return Verdict.STALLED if still >= max(self.stall_s, self.push_bound_s) else Verdict.RUNNING
        return Verdict.STALLED if still >= self.stall_s else Verdict.RUNNING


class CalibrationTracker:
    """The calibration the host started with a 62, from the 60 frames that follow (polls only).

    A first calibration ends when the calibrated bit goes to 1; a recalibration (bit already 1) when the jaws
    rest at the closed stop with a low current for :data:`CAL_REST_S`. RETRY: a calibrated bit that dropped
    (the time-out), or jaws at rest elsewhere for that long (the calibration is not running: never started,
    timed out before this poll, or aborted by someone else)."""

    def __init__(self, was_calibrated: bool, now: float) -> None:
        self.was_calibrated = was_calibrated
        self._rest_since: float | None = None
        self._rest_where: int | None = None
        self._started = now

    def update(self, r: Reading, now: float) -> Verdict:
        if self.was_calibrated and not r.calibrated:
            return Verdict.RETRY  # the firmware's calibration time-out cleared the bit
        if not self.was_calibrated and r.calibrated:
            return Verdict.ENDED
        # Before the first calibration the position bytes use the firmware's default stops and saturate at 0
        # or 255 over much of the travel: the jaws can move for seconds with a constant byte. So at rest means
        # an idle current there (not merely below the calibration's), for longer.
        threshold, window = (
            (CAL_IDLE_CURRENT_MA, CAL_REST_S) if self.was_calibrated else (IDLE_CURRENT_MA, FIRST_REST_S)
        )
        low = r.current_ma is None or abs(r.current_ma) < threshold
        if not low or r.position != self._rest_where:
            self._rest_since = now if low else None
            self._rest_where = r.position if low else None
            return Verdict.RUNNING
        if self._rest_since is None or now - self._rest_since < window:
            return Verdict.RUNNING
        if self.was_calibrated and r.position >= CAL_CLOSED_BYTE:
            return Verdict.ENDED
        return Verdict.RETRY
