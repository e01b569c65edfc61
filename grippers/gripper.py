"""The vendor-neutral :class:`Gripper`: SI units in, checked against the profile, a device does the rest.

Modelled on bleak's client holding a backend and httpcore's connection holding its parts: the user holds a
Gripper, the Gripper holds a :class:`~grippers.device.Device` (the family's primitives, grippers/device.py)
and gives every user-facing behaviour once, through small collaborators: the limit checks
(limit_checks.py), the motion rule (motions.py, motion_calls.py), the fast-stop latch (fast_stop.py),
servoing (servo_face.py), the optional features (features.py), the link as the user sees it
(connection.py) and the streams (streams.py).
"""

from __future__ import annotations

import threading
from collections.abc import Callable
from typing import TYPE_CHECKING, Any

from .connection import LinkState, Watch
from .device import Device, DeviceContext, StartedRead, StateCallback
from .errors import FastStopActive, GripperError, NotSupported
from .fast_stop import FastStopLatch
from .features import Features
from .limit_checks import ValueChecks
from .motion_calls import GRASP_CLEARANCE, grasp_with_room, named
from .motions import MotionHandle, MotionSupervisor, wait_seconds
from .profile_model import Limits, ProfileBase
from .servo import ServoTarget
from .servo_face import ServoControl

# Re-exported: these lived here before they moved to their own modules; ``from grippers.gripper import
# GripperState`` and the like keep working.
from .states import Capability, DeviceInfo, GraspResult, GraspState, GripperState, MotionResult
from .streams import StateStream, StreamSet, put_dropping_oldest
from .unclosed import close_unreferenced
from .units import to_mm

if TYPE_CHECKING:
    from .face_support import AsyncSupport
    from .servo import ServoStats

__all__ = [
    "Capability",
    "DeviceInfo",
    "FastStopActive",
    "GraspResult",
    "GraspState",
    "Gripper",
    "GripperState",
    "MotionResult",
    "StartedRead",
    "StateCallback",
    "StateStream",
    "put_dropping_oldest",
]


class Gripper:
    """A gripper in SI units (m, m/s, N, A). Open one with :func:`grippers.open`; a backend's ``open()``
    returns ``Gripper(device, profile, url, timeout=...)``.

    Every value is checked against the limits before anything is sent (``LimitError``, also a
    ``ValueError``); every wait has a timeout (``GripperTimeout``, also a ``TimeoutError``); ``state()`` may
    be called from any thread at any time, also while a motion runs. One motion runs at a time and the newer
    one wins; a motion ended early raises ``CommandFailed`` "superseded by …" or "aborted by …", and Ctrl-C
    stops the gripper before it leaves a blocking call (grippers/motions.py).
    """

    GRASP_CLEARANCE = GRASP_CLEARANCE  # m: where grasp() opens to when the jaws start inside the part

    def __init__(self, device: Device, profile: ProfileBase, url: str, *, timeout: float) -> None:
        self.device = device
        self.profile = profile
        self.url = url
        self.timeout = timeout
        self.capabilities = frozenset(device.capabilities)
        self.simulator: Any = None  # a sim:// gripper's in-process simulator (its model and fault hooks)
        self._profile_assumed = device.profile_assumed  # what grippers.open warns of (ProfileAssumed)
        self._lock = threading.Lock()
        self._checks = ValueChecks(self.name, profile, device.narrow_limits(profile.limits()))
        self._latch = FastStopLatch(self.name, device)
        self._features = Features(self.name, device)
        self._link = LinkState(self.name, device)
        self._on_close = self._link.on_close  # run last at close (grippers.open's sim:// server)
        self._streams = StreamSet()
        self._motions = MotionSupervisor(
            self._lock,
            device=lambda: self.name,
            check_open=self._check_open,
            is_closed=lambda: self._closed,
            stop=device.stop,
            supersede=device.supersede if device.moves_to_new_targets else device.stop,
            settle_time=lambda: device.settle_time(self.timeout),
        )
        self._servo = ServoControl(self.name, device, self._lock, self._motions, timeout)
        device.bind(
            DeviceContext(
                name=self.name,
                closed=lambda: self._closed,
                check_same_device=self._link.check_same_device,
                reconnects=lambda: self._link.watch is not None,
            )
        )
        if device.liveness is not None:  # a link lost for good ends servoing before the user is told
            device.liveness.add_listener(lambda up: None if up else self._servo.end(stop_device=False))
        self._closed = False  # last: a gripper whose __init__ failed has nothing for __del__ to close

    @property
    def name(self) -> str:
        """``PROFILE@URL``: how errors and logs name this gripper."""
        return f"{self.profile.name}@{self.url}"

    @property
    def driver(self) -> Any:
        """The vendor client underneath, for vendor extras the common interface does not cover."""
        return self.device.driver

    @property
    def limits(self) -> Limits:
        """The limits in force: the profile's, narrowed by the device's own."""
        return self._checks.limits

    @limits.setter
    def limits(self, limits: Limits) -> None:
        self._checks.limits = limits

    # -- the checks every call makes ----------------------------------------------------------------------

    def _check_open(self, command: str) -> None:
        if self._closed:
            raise GripperError("the gripper is closed", device=self.name, command=command)
        self._link.check(command)  # during an outage: ConnectionLost at once, nothing waits

    def _check_motion(self, command: str) -> None:
        self._check_open(command)
        if self._latch.active and self.device.fast_stop_shared:
            try:  # another client may have acknowledged it: the device's state is the truth
                self.state()
            except GripperError:
                pass
        if command != "servo" and self._servo.loop is not None:
            self._servo.end(stop_device=True)  # a motion command takes over from servoing
        self._latch.refuse(command)

    def _timeout(self, timeout: float | None, command: str, distance: float, speed: float) -> float:
        seconds = wait_seconds(timeout, command, self.name)
        if seconds is None:
            return self._motion_timeout(distance, speed)
        return min(seconds, threading.TIMEOUT_MAX / 4)

    def _motion_timeout(self, distance: float, speed: float) -> float:
        """A bound on a motion's duration when the caller gives none: twice the travel time plus slack."""
        return self.device.motion_timeout(2.0 * distance / max(speed, 1e-6) + 2.0 + self.timeout)

    def _run_motion(
        self, name: str, call: Callable[[], Any], wait: bool, *, timeout: float, what: str = ""
    ) -> Any:
        """Run a device motion under the one rule (grippers/motions.py): supersede, abort, Ctrl-C stops."""
        body = lambda: named(name, self.name, lambda: self._latch.latching(call))  # noqa: E731
        return self._motions.run(name, body, wait, timeout=timeout, what=what)

    # -- motions ------------------------------------------------------------------------------------------

    def home(self, timeout: float | None = None, *, wait: bool = True) -> None | MotionHandle[None]:
        """Reference the axis (WSG homing) or calibrate the stroke (MSG); blocks until done."""
        self._check_motion("home")
        t = self._timeout(timeout, "home", 2 * self.limits.stroke, 0.02)
        return self._run_motion("home", lambda: self.device.home(t), wait, timeout=t)

    def move(
        self, width: float, speed: float | None = None, *, wait: bool = True, timeout: float | None = None
    ) -> MotionResult | MotionHandle[MotionResult]:
        """Move the fingers to ``width`` (m) at ``speed`` (m/s; default from the profile)."""
        w, s = self._checks.width(width, "move"), self._checks.speed(speed, "move")
        self._check_motion("move")
        t = self._timeout(timeout, "move", self.limits.stroke, s)
        call = lambda: self.device.move(w, s, t)  # noqa: E731
        return self._run_motion("move", call, wait, timeout=t, what=f" to {to_mm(w):g} mm")

    def grasp(
        self,
        width: float,
        speed: float | None = None,
        force: float | None = None,
        *,
        wait: bool = True,
        timeout: float | None = None,
    ) -> GraspResult | MotionHandle[GraspResult]:
        """Close on a part of nominal ``width`` (m) with ``force`` (N); ``.grasped`` says if it is held.

        When the jaws start inside the part's width they first open to the width plus ``GRASP_CLEARANCE``
        (within the limits), then grasp; for a part gripped from inside the other way round."""
        c = self._checks
        w, s, f = c.width(width, "grasp"), c.speed(speed, "grasp"), c.force(force, "grasp")
        self._check_motion("grasp")
        t = self._timeout(timeout, "grasp", self.limits.stroke, s)
        call = lambda: grasp_with_room(self.device, self.limits, self._motions, self._latch, (w, s, f, t))  # noqa: E731
        return self._run_motion("grasp", call, wait, timeout=2 * t, what=f" {to_mm(w):g} mm")

    def release(
        self,
        width: float | None = None,
        speed: float | None = None,
        *,
        wait: bool = True,
        timeout: float | None = None,
    ) -> MotionResult | MotionHandle[MotionResult]:
        """Open to ``width`` (m; default fully open) and end a grasp."""
        if width is None:
            w = self.device.default_release_width(self.limits.max_width, self.limits.min_width)
        else:
            w = self._checks.width(width, "release")
        s = self._checks.speed(speed, "release")
        self._check_motion("release")
        t = self._timeout(timeout, "release", self.limits.stroke, s)
        call = lambda: self.device.release(w, s, t)  # noqa: E731
        return self._run_motion("release", call, wait, timeout=t, what=f" to {to_mm(w):g} mm")

    def stop(self) -> None:
        """Stop the fingers where they are; a running motion raises CommandFailed "aborted by stop()".

        The WSG keeps its motor on; the MSG clears its action bit (CAN) or, having no other way over UART,
        deactivates the motor, so a held part is no longer squeezed."""
        self._check_open("stop")
        self._servo.end(stop_device=False)  # stop() ends servoing; the stop below halts its motion
        self._motions.abort("stop()")

    def fast_stop(self) -> None:
        """Stop at once; further motion is refused until :meth:`acknowledge`. A running motion raises
        CommandFailed "aborted by fast_stop()"."""
        self._check_open("fast_stop")
        self._servo.end(stop_device=False)
        # Refuse motion from here on, even if the reply is lost or another thread starts a move meanwhile:
        # the user asked for a stop, and acknowledge() is the one way out.
        self._latch.active = True
        self._motions.abort("fast_stop()", device_stop=self.device.fast_stop)

    def acknowledge(self) -> None:
        """Clear a fast stop (WSG 24h; MSG: estop bit cleared, then the error)."""
        self._check_open("acknowledge")
        self.device.acknowledge()
        self._latch.active = False

    # -- servoing -----------------------------------------------------------------------------------------

    def servo(self, width: float, speed: float | None = None, force: float | None = None) -> None:
        """Head for ``width`` (m) now, without waiting: the latest target wins, targets that come faster than
        the device takes them are coalesced. Limits are checked here, on every call; an error the device
        reported for an earlier target is raised here too. stop() (or any motion command) ends servoing."""
        w, s = self._checks.width(width, "servo"), self._checks.speed(speed, "servo")
        f = None if force is None else self._checks.force(force, "servo")
        self._check_motion("servo")
        self._servo.submit(ServoTarget(w, s, f), self._check_open)

    @property
    def servo_stats(self) -> ServoStats | None:
        """Counts of the current (or last) servoing: received, sent, coalesced, unchanged, failed."""
        return self._servo.stats

    @property
    def servoing(self) -> bool:
        """A servoing runs: ``servo()`` targets stream to the device until stop() or a motion command."""
        return self._servo.loop is not None

    def servo_flush(self, timeout: float = 5.0) -> bool:
        """Wait until every target given so far is on the wire (sent, coalesced into a newer one, or found
        unchanged) or servoing ended; False if that took longer than ``timeout`` seconds (a test, a
        benchmark; a control loop never needs it)."""
        return self._servo.flush(wait_seconds(timeout, "servo_flush", self.name))

    # -- reading ------------------------------------------------------------------------------------------

    def state(self) -> GripperState:
        """The jaws now: width (m), speed, force or current, grasp state, faults; readable during a motion.

        Raises:
            GripperTimeout: the device did not answer within the connection's timeout.
            ConnectionLost: the link is down (with ``reconnect=true``: at once during an outage).
            ProtocolError: the answer was malformed (the device or the line is not what the profile says).
            GripperError: the gripper was closed.
        """
        self._check_open("state")
        return self._latch.took(self.device.read_state())

    def _took_state(self, st: GripperState) -> GripperState:  # what state() does with a reading
        return self._latch.took(st)

    def info(self) -> DeviceInfo:
        """What the device is: vendor, model, profile, firmware, serial number and the limits in force
        (``extra["warnings"]``: what the library assumed or ignored).

        Raises:
            GripperTimeout, ConnectionLost, ProtocolError, GripperError: as :meth:`state`.
        """
        self._check_open("info")
        return self.device.info()

    def stream(
        self, rate_hz: float = 50.0, callback: Callable[[GripperState], Any] | None = None
    ) -> StateStream:
        """States at ``rate_hz``; an iterator, or calls ``callback`` from a background thread. Close it."""
        with self._lock:  # registered atomically with the closed check, so close() stops every stream
            self._check_open("stream")
            read = lambda: self._latch.shown(self.device.read_state())  # noqa: E731
            return self._streams.open(self.device.state_source, read, self._link.watch, rate_hz, callback)

    def async_support(self) -> AsyncSupport:
        """The one declared hook of a face built on this gripper (grippers/aio.py; the CLI's commands that
        poll a motion): the non-blocking state read, giving up a cancelled call, the loop as reader, motions
        on the face's threads, stopping the motions a face started without waiting (grippers/face_support.py).
        Not a command (grippers/commands.py's ``FACE_HOOKS``)."""
        from .face_support import AsyncSupport

        return AsyncSupport(self)

    # -- limits and optional features ---------------------------------------------------------------------

    def check(
        self,
        width: float | None = None,
        speed: float | None = None,
        force: float | None = None,
        *,
        command: str = "check",
    ) -> tuple[float | None, float | None, float | None]:
        """Validate values against the limits without sending anything (LimitError naming ``command``);
        returns them as they would be used (speed and force default from the profile when None)."""
        c = self._checks
        w = None if width is None else c.width(width, command)
        return w, c.speed(speed, command), c.force(force, command)

    def require(self, capability: Capability, command: str) -> None:
        """NotSupported naming ``command`` unless the device has ``capability``; sends nothing."""
        self._features.require(capability, command)

    def temperature(self) -> float:
        """The gripper's (or its driver's) temperature in °C."""
        self._check_open("temperature")
        return float(self._features.get(Capability.TEMPERATURE, "temperature").read())

    def set_soft_limits(self, min_width: float, max_width: float) -> None:
        """Limits the device itself enforces on finger motion (m)."""
        lo, hi = self._checks.soft_limits(min_width, max_width)
        self._check_open("set_soft_limits")
        self._features.get(Capability.SOFT_LIMITS, "set_soft_limits").set(lo, hi)

    def clear_soft_limits(self) -> None:
        """Remove the limits :meth:`set_soft_limits` set in the device."""
        self._check_open("clear_soft_limits")
        self._features.get(Capability.SOFT_LIMITS, "clear_soft_limits").set(None, None)

    def device_tag(self) -> str:
        """The user-defined name stored in the device."""
        self._check_open("device_tag")
        return str(self._features.get(Capability.DEVICE_TAG, "device_tag").read())

    def set_device_tag(self, tag: str) -> None:
        """Store ``tag`` as the device's user-defined name."""
        self._check_open("set_device_tag")
        self._features.get(Capability.DEVICE_TAG, "set_device_tag").write(tag)

    # -- the link -----------------------------------------------------------------------------------------

    @property
    def link_watch(self) -> Watch | None:
        """With ``reconnect=true``: the watch that brings a lost link back (its ``policy``, ``epoch``,
        ``attempts``, ``last_error``); None when reconnection is off. Read it; the gripper drives it."""
        return self._link.watch

    @property
    def connected(self) -> bool:
        """False while a lost link is being re-established (reconnect=true), once it is lost for good, or
        after close()."""
        return self._link.connected(self._closed)

    def on_connection(self, callback: Callable[[bool], Any]) -> Callable[[], None]:
        """Call ``callback(connected)`` from a background thread whenever the link is lost or back; returns
        a function that unregisters it. Without reconnect=true only a loss (once) or close() is reported."""
        return self._link.on_connection(callback)

    def _reconnect(self) -> None:
        """Bring the device's link back (grippers/reconnect.py's watch): NotSupported without the feature."""
        r = self.device.reconnection
        if r is None:
            raise NotSupported("this device cannot reconnect", device=self.name, command="reconnect")
        r.reconnect()
        self._latch.take_device()
        self.limits = self.device.narrow_limits(self.profile.limits())  # a restarted device may differ

    # -- the end ------------------------------------------------------------------------------------------

    def close(self) -> None:
        """End the session: stop streams, let running motions end (bounded), release the transport.
        Idempotent. It does not move the jaws (``close()`` ends the session here; to close the jaws on a
        part, :meth:`grasp`: docs/api.md, "Vocabulary"); the next call raises "the gripper is closed"."""
        with self._lock:  # a second close() returns at once; nothing registers behind our back
            if self._closed:
                return
            self._closed = True
            streams, handles = self._streams.take_all(), self._motions.take_all()
            servo, watch, self._link.watch = self._servo.take(), self._link.watch, None
        self._latch.forget()
        if servo is not None:
            servo.end(self.timeout + 1.0)
        if watch is not None:
            watch.close()
        for s in streams:
            s.close()
        try:
            self.device.close()
        finally:
            for h in handles:
                h.join(5.0)
            for fn in reversed(self._on_close):
                fn()

    def __del__(self) -> None:  # closed when nobody references it, with a ResourceWarning
        close_unreferenced(self, "gripper", self.close)

    def __enter__(self) -> Gripper:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()

    def __repr__(self) -> str:
        return f"<{type(self).__name__} {self.name}{' closed' if self._closed else ''}>"
