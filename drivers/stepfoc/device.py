"""One MSG gripper (STEPFOC driver) as one object, over a CAN or a UART link, in device units.

The shape of pymodbus's framer/transport split: the link (device_links.py) turns requests into its wire's
frames or text lines; this object owns what they mean for a motion, once for both wires:

* status and the "moving" rule of a state read (:meth:`StepfocDevice.moving`);
* go, halt, calibrate, e-stop, clear, each taking a new number from the supersede counter
  (:class:`~grippers.drivers.motion_epochs.MotionEpochs`), so a wait of an older motion ends with the newer
  one's cause and never as done;
* the poll loop that feeds the sans-IO trackers (motion.py :class:`MotionTracker` /
  :class:`CalibrationTracker`, uart_calibration.py on the UART): the ONE rule for the end of a motion;
* the shared-bus registry (:class:`~.device_links.CanLink`: one bus per channel in a process).

Position 0 is fully open and 255 closed, speed a byte, current mA: a backend maps SI onto these
(grippers/backends/stepfoc.py). Errors are the driver's (grippers.drivers.errors): an e-stop seen during a
wait is ``CommandFailed`` with ``status_name="fast_stop"``, a gripper that lost its calibration
``status_name="not calibrated"``, so a caller above can name them in its own terms.
"""

from __future__ import annotations

import threading
import time
from collections.abc import Callable
from typing import TYPE_CHECKING, Any

from ..errors import CommandFailed, ConnectionLost, GripperTimeout
from ..motion_epochs import MotionEpochs
from .can_protocol import Detection
from .device_links import CanLink, Link, Status, StatusCallback, UartLink
from .motion import STALL_MIN_S, MotionTracker, Verdict

if TYPE_CHECKING:
    import asyncio

__all__ = ["FAST_STOP", "NOT_CALIBRATED", "CanLink", "Link", "Status", "StepfocDevice", "UartLink"]

POLL_PERIOD = 0.01  # s between status polls while waiting for a motion; a CAN round trip is ~0.2 ms
# Stalled for STALL_MIN_S (motion.py) and at least STALL_STEPS position steps at the commanded speed, a
# motion's wait ends with "aborted".
STALL_STEPS = 4
# moving(): the bits alone would say "moving" for ever once the driver was idled (clear error, idle,
# watchdog) with the stored 61's activate and action bits still set and detection 0 (the firmware's "idle or
# disabled" branch). While no motion waits, the jaws decide: standing still this long is not moving.
STILL_S = 0.3

FAST_STOP = "fast_stop"  # status_name of the CommandFailed a wait raises when it sees the e-stop
NOT_CALIBRATED = "not calibrated"  # ... and when the jaws stalled on a gripper that lost its calibration


def stall_seconds(step_s: float) -> float:
    """How long the jaws may stand still before a motion counts as stalled, given the seconds one position
    step takes at the commanded speed."""
    return max(STALL_MIN_S, STALL_STEPS * step_s)


class _Retry(Exception):
    """The calibration ended without success; it may be started once more."""

    def __init__(self, status: Status) -> None:
        super().__init__("calibration ended without success")
        self.status = status


class StepfocDevice:
    """One MSG over ``link``. ``name`` names it in errors; ``where(position)`` words a position in them
    (a backend gives millimetres); ``closed()`` ends a wait when the owner closed (default: never)."""

    def __init__(self, link: Link, *, name: str = "", where: Callable[[int], str] | None = None) -> None:
        self.link = link
        self.name = name or str(getattr(link.driver, "device", "stepfoc"))
        self.where = where or (lambda position: f"position {position}")
        self.closed: Callable[[], bool] = lambda: False
        self.epochs = MotionEpochs()  # every motion and stop takes a number: older waits end
        self._send_lock = threading.RLock()  # a motion's number and its frames go out together
        # The calibrated bit as last read (None: not read since open or a reconnection). The firmware ignores
        # a motion frame until it is calibrated (Gripper_mode, docs/protocols.md §2), so a motion asks first
        # unless a read already said so: the bit is lost only at power-off (a reconnection).
        self.calibrated: bool | None = None
        self._waits = 0  # motion waits in progress (moving() trusts the bits while one runs)
        self._waits_lock = threading.Lock()
        self._seen_position: int | None = None  # the last position read and when it last changed
        self._seen_change = 0.0
        self._servo_first = True

    @property
    def driver(self) -> Any:
        """The client underneath (:class:`~.can_client.StepfocNode` or :class:`~.uart_client.StepfocUart`)."""
        return self.link.driver

    # -- status ------------------------------------------------------------------------------------------

    def status(self) -> Status:
        st = self.link.status()
        self.calibrated = bool(st.calibrated)
        return st

    def start_status(self, done: StatusCallback) -> Callable[[], None] | None:
        """:meth:`status` without blocking (CAN only; None: read by blocking); returns what gives it up."""

        def finished(st: Status | None, error: BaseException | None) -> None:
            if st is not None:
                self.calibrated = bool(st.calibrated)
            done(st, error)

        return self.link.start_status(finished)

    def moving(self, st: Status) -> bool:
        """Whether the jaws move, by a status just read: the bits, and while no motion of ours waits the
        jaws too (an idled driver keeps reporting "moving" with its stored bits)."""
        now = time.monotonic()
        if st.position != self._seen_position:
            self._seen_position, self._seen_change = st.position, now
        if not (st.detection == Detection.MOVING and st.activated and st.action and st.calibrated):
            return False
        return self._waits > 0 or now - self._seen_change < STILL_S

    def require_calibrated(self, command: str) -> Status | None:
        """CommandFailed (``NOT_CALIBRATED``) before anything is sent to an uncalibrated gripper: the firmware
        ignores its motions (``action && calibrated && activated``, PCrnjak/STEPFOC-stepper-controller
        ``src/motor_control.cpp`` ``Gripper_mode``; the simulator's ``_apply_motion`` follows it) and a wait
        would end as a stall. Returns the status it read, None when a read already said so."""
        st = None
        if self.calibrated is not True:
            st = self.status()
        if not self.calibrated:
            raise CommandFailed(
                f"{command} refused: the gripper is not calibrated",
                status_name=NOT_CALIBRATED,
                device=self.name,
                command=command,
            )
        return st

    # -- motions -----------------------------------------------------------------------------------------

    def go(
        self, command: str, position: int, speed: int, current_ma: int, timeout: float, *, stall_s: float
    ) -> Status:
        """Send a motion and wait for its end: the status that ended it (ARRIVED or OBJECT)."""
        with self._send_lock:  # a halt cannot land between the number and the frames and be undone
            motion = self.epochs.begin(f"superseded by a newer motion before it ended ({command})")
            self.link.go(position, speed, current_ma)
        # The immediate reply to a new command still carries the previous detection value (docs/protocols.md
        # §2), so fresh polls decide, read by the tracker: 3 only at the target (the latch can say 3 early),
        # 1/2 only once the jaws moved or it lasted (the start-up current can say it early), and a slow
        # motion's late contact flag is waited for while the current shows the jaws pushing.
        tracker = MotionTracker(None, position, time.monotonic(), stall_s=stall_s, limit_ma=current_ma)
        return self._wait(command, motion, timeout, lambda st, now: tracker.update(st.reading(), now), True)

    def calibrate(self, timeout: float, *, command: str = "home") -> Status:
        """Start a calibration and wait for its end (polls only: a motion frame would abort it). One that
        ended without success (the firmware's time-out, reached by the ticks an aborted one left behind, or
        one that never ran) is started once more: the time-out resets its step state."""
        with self._send_lock:
            motion = self.epochs.begin(f"superseded by a newer motion before it ended ({command})")
            self.link.calibrate()
        deadline = time.monotonic() + timeout
        for attempt in range(2):
            try:
                left = max(0.1, deadline - time.monotonic())
                st = self._wait(command, motion, left, self.link.calibration_verdict, False)
                # ENDED means the calibrated bit was seen set, but over UART by the verdict's own reads, which
                # may come after the poll ``st`` (taken while it still ran): the verdict is the newer word.
                self.calibrated = True
                return st
            except _Retry as retry:
                if attempt:
                    raise CommandFailed(
                        "calibration did not complete twice (the jaws rest at "
                        f"{self.where(retry.status.position)}, calibrated {int(retry.status.calibrated)})",
                        status_name="failed",
                        device=self.name,
                        command=command,
                    ) from None
                with self._send_lock:
                    self.epochs.check(motion, command=command, device=self.name)
                    self.link.calibrate()
        raise AssertionError("unreachable")  # pragma: no cover

    def halt(self, cause: str = "aborted by stop()") -> None:
        """Stop where the jaws are; a waiting motion ends with ``cause``. Safe from another thread and from
        a KeyboardInterrupt handler: the wait learns of it from the counter, the link serialises frames."""
        with self._send_lock:
            self.epochs.begin(cause)
            self.link.halt()

    def estop(self, cause: str = "aborted by fast_stop()") -> None:
        self.epochs.begin(cause)  # no lock: an e-stop never waits for anything
        self.link.estop()

    def clear(self) -> None:
        """Clear the e-stop and the driver's error (the order the firmware needs is the link's)."""
        self.link.clear()

    def servo(self, position: int, speed: int, current_ma: int) -> bool:
        """One streamed target, no wait; False if the gripper already heads there (:meth:`servo_begin`
        first)."""
        if not self.link.servo(position, speed, current_ma, first=self._servo_first):
            return False
        self._servo_first = False
        return True

    def servo_begin(self) -> None:
        self._servo_first = True

    # -- the poll loop -----------------------------------------------------------------------------------

    def _wait(
        self,
        command: str,
        motion: int,
        timeout: float,
        verdict: Callable[[Status, float], Verdict],
        motion_bits: bool,
    ) -> Status:
        """Poll until ``verdict`` says ARRIVED, OBJECT or ENDED. Ends early, never as done, when a newer
        motion or a stop began, the device shows an e-stop or an error, (``motion_bits``) the action or
        activate bit was cleared by someone else, or the tracker says STALLED; RETRY is for
        :meth:`calibrate`."""
        with self._waits_lock:
            self._waits += 1
        try:
            deadline = time.monotonic() + timeout
            while True:
                if self.closed():  # do not poll a closed link until the deadline
                    raise ConnectionLost(
                        "the gripper was closed during the motion", device=self.name, command=command
                    )
                self.epochs.check(motion, command=command, device=self.name)
                st = self.status()
                self.epochs.check(motion, command=command, device=self.name)  # a stop sent during this poll
                self._check_faults(st, command)
                now = time.monotonic()
                if motion_bits and not (st.activated and st.action):
                    raise CommandFailed(
                        f"{command} aborted: the gripper's action bit was cleared (a stop from another "
                        f"program?) at {self.where(st.position)}",
                        status_name="aborted",
                        device=self.name,
                        command=command,
                    )
                v = verdict(st, now)
                if v in (Verdict.ARRIVED, Verdict.OBJECT, Verdict.ENDED):
                    return st
                if v is Verdict.RETRY:
                    raise _Retry(st)
                if v is Verdict.STALLED:
                    self._stalled(st, command)
                if now >= deadline:
                    raise GripperTimeout(f"not done after {timeout:g} s", device=self.name, command=command)
                time.sleep(POLL_PERIOD)
        finally:
            with self._waits_lock:
                self._waits -= 1

    def _check_faults(self, st: Status, command: str) -> None:
        if st.estop:
            raise CommandFailed(
                f"{command} aborted: e-stop active on the gripper",
                status_name=FAST_STOP,
                device=self.name,
                command=command,
            )
        if st.faults:  # a watchdog or temperature error idles the driver; waiting would only time out
            raise CommandFailed(
                f"{command} aborted by a device error: {', '.join(st.faults)}",
                status_name=",".join(st.faults),
                device=self.name,
                command=command,
            )

    def _stalled(self, st: Status, command: str) -> None:
        if not st.calibrated and command != "home":  # powered off and on behind our back
            raise CommandFailed(
                f"{command} refused: the gripper is not calibrated",
                status_name=NOT_CALIBRATED,
                device=self.name,
                command=command,
            )
        raise CommandFailed(
            f"{command} aborted: the jaws stopped at {self.where(st.position)} without reaching the target "
            "(the driver was idled or the motion stalled)",
            status_name="aborted",
            device=self.name,
            command=command,
        )

    # -- link life ---------------------------------------------------------------------------------------

    def alive(self) -> bool:
        return self.link.alive()

    def reconnect(self) -> None:
        """Reach the device again after the link was lost (a fresh link where the old one cannot recover).
        A gripper that was power-cycled has lost its calibration (docs/protocols.md §2): read it afresh."""
        link = self.link
        fresh = link.reopened()
        if fresh is not link:
            self.link = fresh
            link.close()
        self.calibrated = None

    def read_on(self, loop: asyncio.AbstractEventLoop) -> Callable[[], None] | None:
        return self.link.read_on(loop)  # CAN only: the UART client reads on the calling thread

    def abandon(self, thread_ident: int) -> None:
        self.link.abandon(thread_ident)

    def resume(self, thread_ident: int) -> None:
        self.link.resume(thread_ident)

    def close(self) -> None:
        self.link.close()
