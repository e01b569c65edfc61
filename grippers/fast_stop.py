"""The fast-stop latch of a :class:`~grippers.gripper.Gripper`, the same for every family.

After ``fast_stop()`` motion is refused (FastStopActive) until ``acknowledge()``, also when the stop's reply
was lost or another thread starts a move meanwhile. A device that latches its fast stop itself
(``Device.reports_fast_stop``, the WSG's SF_FAST_STOP) is the truth: every state read takes its word, also
for a stop raised or cleared by another program. A device without a fast-stop state of its own (a Robotiq)
gets the latch from here, shown as the ``"fast_stop"`` fault in its states until ``acknowledge()``.
"""

from __future__ import annotations

import dataclasses
import logging
import warnings
from collections.abc import Callable
from typing import TypeVar

from .device import Device
from .errors import FastStopActive, FastStopForgotten
from .states import GripperState

T = TypeVar("T")

log = logging.getLogger(__name__)

FAST_STOP_FAULT = "fast_stop"
"""The fault a gripper adds to the states of a device that does not report its fast stop itself."""


class FastStopLatch:
    """Whether motion is refused for a fast stop, and what every state read does with it."""

    def __init__(self, name: str, device: Device) -> None:
        self.name = name
        self.device = device
        self.active = False
        self._faults_logged: tuple[str, ...] = ()  # what a state read last logged (INFO, issue 22 §3)
        self.take_device()

    def take_device(self) -> None:
        """A device that latches its fast stop itself: its latch is the gripper's from the start (and again
        after a reconnection), before any state was read."""
        if self.device.reports_fast_stop:
            self.active = self.device.fast_stop_latched()

    def refuse(self, command: str) -> None:
        if self.active:
            raise FastStopActive(
                "fast stop is active: call acknowledge() before moving", device=self.name, command=command
            )

    def latching(self, call: Callable[[], T]) -> T:
        """A motion the device ended with FastStopActive (an e-stop raised by another program, seen
        mid-motion) latches the gripper at once, as fast_stop() does: the next motion is refused until
        acknowledge(), not sent into the stop."""
        try:
            return call()
        except FastStopActive:
            self.active = True
            raise

    def forget(self) -> None:
        """At close: a latch that lived only here (the device keeps none) ends with this gripper; say so, or
        the next command would move a gripper its user believes stopped (:class:`FastStopForgotten`).

        Why not a latch that outlives the process (a file per device): a Robotiq has no serial number in its
        registers, so the file could only be keyed by the address, and would latch whatever gripper is next
        plugged into that port (or a simulator started later on a reused port), while the robot program,
        the URCap or a PLC driving the same gripper would ignore it anyway."""
        if self.active and not self.device.reports_fast_stop:
            warnings.warn(
                FastStopForgotten(
                    f"{self.name}: the fast stop ends with this session: the device keeps no fast-stop latch "
                    "of its own, so the next command or program that opens it can move it without "
                    "acknowledge() (grippers ack); keep a program holding the gripper, or use the robot's "
                    "own stop"
                ),
                stacklevel=3,
            )

    def shown(self, st: GripperState) -> GripperState:
        """A device that keeps no fast-stop state of its own: the latch shows in the state, and a state read
        does not clear it (only ``acknowledge()`` does)."""
        if self.device.reports_fast_stop or not self.active or FAST_STOP_FAULT in st.faults:
            return st
        return dataclasses.replace(st, faults=(*st.faults, FAST_STOP_FAULT))

    def took(self, st: GripperState) -> GripperState:
        """What every face does with a state read (threaded, asyncio): one rule in one place."""
        st = self.shown(st)
        # The device is the truth: a fast stop raised or acknowledged elsewhere (another program, the web
        # interface, the vendor extras in .driver) is taken over here.
        self.active = st.fast_stopped
        if st.faults != self._faults_logged:  # a fault raised or cleared: said once, at INFO
            self._faults_logged = st.faults
            log.info("%s: faults: %s", self.name, ", ".join(st.faults) or "none")
        return st
