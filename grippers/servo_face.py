"""``Gripper.servo``: streamed targets, the caller's loop never waits (the sending loop is grippers/servo.py).

A mixin of :class:`~grippers.gripper.Gripper`, apart from its core: a backend that can servo overrides the
three ``_servo*`` hooks declared here; the rest of the gripper only ends servoing when another motion
command takes over (``_end_servo``) and at close.
"""

from __future__ import annotations

import threading
from abc import abstractmethod
from typing import TYPE_CHECKING

from .errors import NotSupported
from .limit_checks import LimitChecks
from .motions import wait_seconds

if TYPE_CHECKING:
    from .motions import MotionSupervisor
    from .servo import ServoLoop, ServoStats, ServoTarget


class ServoFace(LimitChecks):
    """servo(), its counters, and the hooks a backend implements to stream targets."""

    timeout: float
    _lock: threading.Lock
    _motions: MotionSupervisor
    _servo_loop: ServoLoop | None
    _last_servo_loop: ServoLoop | None

    @abstractmethod
    def _check_motion(self, command: str) -> None: ...

    def servo(self, width: float, speed: float | None = None, force: float | None = None) -> None:
        """Head for ``width`` (m) now, without waiting: the latest target wins, targets that come faster than
        the device takes them are coalesced. Limits are checked here, on every call; an error the device
        reported for an earlier target is raised here too. stop() (or any motion command) ends servoing."""
        from .servo import ServoLoop, ServoTarget

        w, s = self._width(width, "servo"), self._speed(speed, "servo")
        f = None if force is None else self._force(force, "servo")
        self._check_motion("servo")
        if self._servo_loop is None:  # servoing begins: it takes over from a running motion, which ends now
            self._motions.supersede(f"servo to {w * 1000:g} mm")
        with self._lock:
            self._check_open("servo")
            loop = self._servo_loop
            if loop is None:
                self._servo_begin()
                loop = self._servo_loop = ServoLoop(self.name, self._servo)
        loop.submit(ServoTarget(w, s, f))

    @property
    def servo_stats(self) -> ServoStats | None:
        """Counts of the current (or last) servoing: received, sent, coalesced, unchanged, failed."""
        loop = self._servo_loop or self._last_servo_loop
        return None if loop is None else loop.stats

    @property
    def servoing(self) -> bool:
        """A servoing runs: ``servo()`` targets stream to the device until stop() or a motion command."""
        return self._servo_loop is not None

    def servo_flush(self, timeout: float = 5.0) -> bool:
        """Wait until every target given so far is on the wire (sent, coalesced into a newer one, or found
        unchanged) or servoing ended; False if that took longer than ``timeout`` seconds.

        For a program that reads the state or the counters right after its last target (a test, a
        benchmark); a control loop never needs it, the latest target wins anyway."""
        seconds = wait_seconds(timeout, "servo_flush", self.name)
        loop = self._servo_loop
        return True if loop is None else loop.flush(seconds if seconds is not None else threading.TIMEOUT_MAX)

    def _end_servo(self, *, stop_device: bool) -> None:
        with self._lock:
            loop, self._servo_loop = self._servo_loop, None
        if loop is None:
            return
        self._last_servo_loop = loop
        loop.end(self.timeout + 1.0)
        if stop_device:
            self._servo_end()

    # Backends that can servo override these three (grippers/backends/wsg.py, stepfoc.py).
    def _servo_begin(self) -> None:
        """Called (under the lock) before the first target of a servoing; NotSupported by default."""
        raise NotSupported("this backend cannot stream targets", device=self.name, command="servo")

    def _servo(self, target: ServoTarget) -> bool | None:
        """Put one target on the wire without waiting for the motion; False if nothing needed sending, None
        to put it off (grippers/servo.py offers it again)."""
        raise NotSupported("this backend cannot stream targets", device=self.name, command="servo")

    def _servo_end(self) -> None:
        """Servoing ended for another motion command: leave the device ready to take it."""
        return None
