"""The gripper over a :class:`~grippers.device.Device`: the contract's primitives behind every face.

A backend's ``open()`` returns ``DeviceGripper(device, profile, url, timeout=...)``; everything the user
sees (limits, defaults, the motion rule, streams, servoing, reconnection, the fast-stop latch, close) is
:class:`~grippers.gripper.Gripper`'s, the same for every family. This class only maps the gripper's
internal hooks onto the device's public contract, so a family written outside the repository names no
private member of the library.
"""

from __future__ import annotations

import dataclasses
from collections.abc import Callable
from typing import TYPE_CHECKING, Any, TypeVar

from .device import Device, DeviceContext, StartedRead, StateCallback
from .errors import FastStopActive, NotSupported
from .gripper import Gripper
from .profile_model import ProfileBase
from .states import DeviceInfo, GraspResult, GripperState, MotionResult

if TYPE_CHECKING:
    import asyncio

    from .servo import ServoTarget

T = TypeVar("T")

FAST_STOP_FAULT = "fast_stop"
"""The fault a gripper adds to the states of a device that does not report its fast stop itself."""


class DeviceGripper(Gripper):
    """A :class:`~grippers.gripper.Gripper` holding a :class:`~grippers.device.Device`."""

    def __init__(self, device: Device, profile: ProfileBase, url: str, *, timeout: float) -> None:
        self.device = device
        self.capabilities = frozenset(device.capabilities)
        super().__init__(profile, url, timeout=timeout)
        self.limits = device.narrow_limits(self.limits)
        self._profile_assumed = device.profile_assumed  # what grippers.open warns of (ProfileAssumed)
        device.bind(
            DeviceContext(
                name=self.name, closed=lambda: self._closed, check_same_device=self._check_same_device
            )
        )
        self._take_latch()

    def _take_latch(self) -> None:
        """A device that latches its fast stop itself: its latch is the gripper's from the start (and again
        after a reconnection), before any state was read."""
        if self.device.reports_fast_stop:
            self._fast_stopped = self.device.fast_stop_latched()

    @property
    def driver(self) -> Any:
        return self.device.driver

    # -- the primitives ------------------------------------------------------------------------------------

    def _latching(self, call: Callable[[], T]) -> T:
        """A motion the device ended with FastStopActive (an e-stop raised by another program, seen
        mid-motion) latches the gripper at once, as fast_stop() does: the next motion is refused until
        acknowledge(), not sent into the stop."""
        try:
            return call()
        except FastStopActive:
            self._fast_stopped = True
            raise

    def _home(self, timeout: float) -> None:
        self._latching(lambda: self.device.home(timeout))

    def _move(self, width: float, speed: float, timeout: float) -> MotionResult:
        return self._latching(lambda: self.device.move(width, speed, timeout))

    def _grasp(self, width: float, speed: float, force: float, timeout: float) -> GraspResult:
        return self._latching(lambda: self.device.grasp(width, speed, force, timeout))

    def _release(self, width: float, speed: float, timeout: float) -> MotionResult:
        return self._latching(lambda: self.device.release(width, speed, timeout))

    def _stop(self) -> None:
        self.device.stop()

    def _fast_stop(self) -> None:
        self.device.fast_stop()

    def _acknowledge(self) -> None:
        self.device.acknowledge()

    def _supersede(self) -> None:
        if self.device.moves_to_new_targets:
            self.device.supersede()
        else:
            self.device.stop()

    def _state(self) -> GripperState:
        return self._with_latch(self.device.read_state())

    def _with_latch(self, st: GripperState) -> GripperState:
        """A device that keeps no fast-stop state of its own: the gripper's latch shows in the state, and a
        state read does not clear it (only ``acknowledge()`` does)."""
        if self.device.reports_fast_stop or not self._fast_stopped or FAST_STOP_FAULT in st.faults:
            return st
        return dataclasses.replace(st, faults=(*st.faults, FAST_STOP_FAULT))

    def _took_state(self, st: GripperState) -> GripperState:
        if not self.device.reports_fast_stop:
            st = self._with_latch(st)
        return super()._took_state(st)

    def _info(self) -> DeviceInfo:
        return self.device.info()

    def _close(self) -> None:
        self.device.close()

    # -- optional hooks ------------------------------------------------------------------------------------

    def _motion_timeout(self, distance: float, speed: float) -> float:
        return self.device.motion_timeout(super()._motion_timeout(distance, speed))

    def _settle_time(self) -> float:
        return self.device.settle_time(self.timeout)

    def _default_release_width(self) -> float:
        return self.device.default_release_width(self.limits.max_width, self.limits.min_width)

    def _grips_from_inside(self) -> bool:
        return self.device.grips_from_inside

    def _start_state(self, done: StateCallback) -> StartedRead | None:
        return self.device.start_read(done)

    def _abandon(self, thread_ident: int) -> None:
        self.device.abandon(thread_ident)

    def _resume(self, thread_ident: int) -> None:
        self.device.resume(thread_ident)

    def _read_on(self, loop: asyncio.AbstractEventLoop) -> Callable[[], None] | None:
        return self.device.read_on(loop)

    # -- optional features: objects the device offers ------------------------------------------------------

    def _identity(self) -> dict[str, str]:
        # Asked once, when reconnect=true switches reconnection on (grippers/reconnect.py's attach): a device
        # that offers no reconnection refuses it there, at open, instead of a watch that can never reconnect.
        r = self.device.reconnection
        if r is None:
            raise NotSupported("this device cannot reconnect", device=self.name, command="open")
        return r.identity()

    def _link_alive(self) -> bool:
        r = self.device.reconnection
        return True if r is None else r.alive()

    def _reconnect(self) -> None:
        r = self.device.reconnection
        if r is None:
            raise NotSupported("this device cannot reconnect", device=self.name, command="reconnect")
        r.reconnect()
        self._take_latch()

    def _servo_begin(self) -> None:
        if self.device.servo is None:
            raise NotSupported("this device cannot servo", device=self.name, command="servo")
        self.device.servo.begin()

    def _servo(self, target: ServoTarget) -> bool | None:
        assert self.device.servo is not None  # _servo_begin refused a device without it
        return self.device.servo.send(target)

    def _servo_end(self) -> None:
        if self.device.servo is not None:
            self.device.servo.end()

    def _temperature(self) -> float:
        t = self.device.temperature
        if t is None:
            raise NotSupported("this device has no temperature", device=self.name, command="temperature")
        return t.read()

    def _set_soft_limits(self, min_width: float | None, max_width: float | None) -> None:
        s = self.device.soft_limits
        if s is None:
            raise NotSupported("this device has no soft limits", device=self.name, command="set_soft_limits")
        s.set(min_width, max_width)

    def _device_tag(self, tag: str | None) -> str:
        d = self.device.device_tag
        if d is None:
            raise NotSupported("this device has no device tag", device=self.name, command="device_tag")
        if tag is None:
            return d.read()
        d.write(tag)
        return tag
