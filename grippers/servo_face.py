"""``Gripper.servo``'s bookkeeping: the servoing that runs (if any), its device feature, its counters.

A collaborator of :class:`~grippers.gripper.Gripper` (the sending loop is grippers/servo.py): the gripper
checks the values and the motion rule, this object begins a servoing on the device's ``servo`` feature
(``Device.servo``; NotSupported without it), hands targets to the loop, and ends it when another motion
command takes over, at stop(), on a lost link and at close.
"""

from __future__ import annotations

import threading
from collections.abc import Callable

from .device import Device
from .errors import NotSupported
from .motions import MotionSupervisor
from .servo import ServoLoop, ServoStats, ServoTarget
from .units import to_mm


class ServoControl:
    """The servoing of one gripper: at most one :class:`~grippers.servo.ServoLoop` at a time."""

    def __init__(
        self, name: str, device: Device, lock: threading.Lock, motions: MotionSupervisor, timeout: float
    ) -> None:
        self.name = name
        self.device = device
        self.lock = lock  # the gripper's: servoing begins atomically with its closed check
        self.motions = motions
        self.timeout = timeout
        self.loop: ServoLoop | None = None
        self.last: ServoLoop | None = None  # its counters stay readable after it ended

    def submit(self, target: ServoTarget, check_open: Callable[[str], None]) -> None:
        """Queue ``target`` (checked already); the first one of a servoing supersedes the running motion."""
        if self.loop is None:  # servoing begins: it takes over from a running motion, which ends now
            self.motions.supersede(f"servo to {to_mm(target.width):g} mm")
        with self.lock:
            check_open("servo")
            loop = self.loop
            if loop is None:
                feature = self.device.servo
                if feature is None:
                    raise NotSupported("this device cannot servo", device=self.name, command="servo")
                feature.begin()
                loop = self.loop = ServoLoop(self.name, feature.send)
        loop.submit(target)

    @property
    def stats(self) -> ServoStats | None:
        loop = self.loop or self.last
        return None if loop is None else loop.stats

    def flush(self, seconds: float | None) -> bool:
        loop = self.loop
        return True if loop is None else loop.flush(seconds if seconds is not None else threading.TIMEOUT_MAX)

    def end(self, *, stop_device: bool) -> None:
        """End servoing (bounded); ``stop_device``: leave the device ready for the motion taking over."""
        with self.lock:
            loop, self.loop = self.loop, None
        if loop is None:
            return
        self.last = loop
        loop.end(self.timeout + 1.0)
        if stop_device and self.device.servo is not None:
            self.device.servo.end()

    def take(self) -> ServoLoop | None:
        """At close (under the gripper's lock): the running loop, which the caller ends."""
        loop, self.loop = self.loop, None
        return loop
