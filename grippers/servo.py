"""Streamed targets (``Gripper.servo``): the caller's control loop never waits for the wire.

A teleoperation or policy loop sends a target at every control step, often faster than a device can take
commands. :class:`ServoLoop` holds one slot, the latest target (latest wins), and one thread per servoing
gripper (not per call) that puts the slot's content on the wire through the backend's ``_servo`` primitive
whenever the link is free. Targets that arrive while a send is in flight replace each other in the slot and
are counted as coalesced: the device only ever hears the newest one.

An error the device reports for a target (fast stop, lost link) cannot be raised in the thread that sent the
target, which has long returned; it is kept and raised by the next ``servo()`` call, so nothing is lost.
"""

from __future__ import annotations

import logging
import threading
from collections.abc import Callable
from dataclasses import dataclass

from .errors import GripperError

log = logging.getLogger(__name__)

IDLE_WAIT = 0.5  # s: the sender thread's longest sleep; ending servoing wakes it at once anyway
RETRY = 0.01  # s: a deferred target is offered to the backend again this often (unless a newer one comes)


@dataclass(frozen=True, slots=True)
class ServoTarget:
    """One target in SI units, already checked against the limits; ``force`` None keeps the device's."""

    width: float
    speed: float
    force: float | None


@dataclass(slots=True)
class ServoStats:
    """How many targets came in, went on the wire, or were replaced by a newer one before they could."""

    received: int = 0
    sent: int = 0
    coalesced: int = 0
    unchanged: int = 0  # equal to what the device already heads for: nothing to send (MSG's 61 latch)
    deferred: int = 0  # offers the backend put off (WSG: close to the running motion's target)
    failed: int = 0

    @property
    def wire_share(self) -> float:
        return self.sent / self.received if self.received else 0.0


class ServoLoop:
    """The latest-wins slot and its sender thread for one gripper.

    ``send`` is the backend's non-blocking primitive: it puts one target on the wire and returns once the
    device has accepted it (WSG: E_CMD_PENDING; MSG: the 60 reply), never waiting for the motion; it returns
    False when the target needed no frame at all (the device already heads for exactly that), and None to put
    it off (the loop offers it again every :data:`RETRY` seconds until a newer target replaces it).
    """

    def __init__(self, name: str, send: Callable[[ServoTarget], bool | None]) -> None:
        self._send = send
        self._cond = threading.Condition()
        self._slot: ServoTarget | None = None
        self._error: GripperError | None = None
        self._ended = False
        self._busy = False
        self._deferring = False  # a target put off by the backend waits to be offered again
        self.stats = ServoStats()
        self.last_sent: ServoTarget | None = None
        self._thread = threading.Thread(target=self._run, name=f"grippers-servo {name}", daemon=True)
        self._thread.start()

    @property
    def active(self) -> bool:
        return not self._ended

    def submit(self, target: ServoTarget) -> None:
        """Replace the slot's target; raise the error the previous target met on the device, if any."""
        with self._cond:
            error, self._error = self._error, None
            if error is not None:
                raise error
            if self._ended:
                raise GripperError("servoing has ended", command="servo")
            self.stats.received += 1
            if self._slot is not None:
                self.stats.coalesced += 1
            self._slot = target
            self._cond.notify()

    def _run(self) -> None:
        deferred: ServoTarget | None = None
        while True:
            with self._cond:
                if deferred is not None and self._slot is None and not self._ended:
                    self._cond.wait(RETRY)
                while self._slot is None and deferred is None and not self._ended:
                    self._cond.wait(IDLE_WAIT)
                if self._ended:
                    return
                if self._slot is not None:
                    if deferred is not None:
                        self.stats.coalesced += 1  # the put-off target never went out: a newer one did
                    target, self._slot, deferred = self._slot, None, None
                else:
                    assert deferred is not None
                    target, deferred = deferred, None
                self._busy = True
                self._deferring = False
            try:
                on_wire = self._send(target)
            except GripperError as exc:
                with self._cond:
                    self.stats.failed += 1
                    self._error = exc  # raised by the next submit()
            except BaseException:  # a bug in a backend: say so, keep the loop usable
                log.exception("servo send failed")
                with self._cond:
                    self.stats.failed += 1
            else:
                with self._cond:
                    if on_wire is None:
                        deferred = target
                        self._deferring = True
                        self.stats.deferred += 1
                    elif on_wire:
                        self.stats.sent += 1
                        self.last_sent = target
                    else:
                        self.stats.unchanged += 1
            finally:
                with self._cond:
                    self._busy = False
                    self._cond.notify_all()

    def flush(self, timeout: float) -> bool:
        """Wait until the slot is empty and no send is in flight (tests, benchmarks); False on timeout."""
        with self._cond:

            def idle() -> bool:
                return self._ended or (self._slot is None and not self._busy and not self._deferring)

            return self._cond.wait_for(idle, timeout)

    def end(self, timeout: float = 5.0) -> GripperError | None:
        """Drop the unsent target and stop the thread (after the send in flight, bounded by ``timeout``);
        returns the error the last target met, if nobody has seen it yet."""
        with self._cond:
            self._ended = True
            if self._slot is not None:
                self._slot = None
            error, self._error = self._error, None
            self._cond.notify_all()
        if threading.current_thread() is not self._thread:
            self._thread.join(timeout)
        return error
