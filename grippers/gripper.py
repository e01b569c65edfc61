"""The vendor-neutral :class:`Gripper`: SI units in, checked against the profile, a backend does the rest.

Modelled on python-can's ``BusABC``: a backend implements a handful of small primitives in its device's
terms (``_move``, ``_grasp``, ``_state``, …) and this class gives every user-facing behaviour once: limit
checks before anything is sent, defaults from the profile, fast-stop bookkeeping, non-blocking motion
handles, state streams, and release of every resource on close.
"""

from __future__ import annotations

import logging
import threading
from abc import ABC, abstractmethod
from collections.abc import Callable
from typing import TYPE_CHECKING, Any, TypeVar

from .connection import ConnectionHooks, Watch
from .device import StartedRead, StateCallback
from .errors import FastStopActive, GripperError, MotionBlocked, NotReferenced
from .features import OptionalFeatures
from .motions import MotionHandle, MotionSupervisor, wait_seconds
from .profile_model import ProfileBase
from .servo_face import ServoFace

# Re-exported: these lived here before they moved to their own modules; ``from grippers.gripper import
# GripperState`` and the like keep working.
from .states import Capability, DeviceInfo, GraspResult, GraspState, GripperState, MotionResult
from .streams import StateStream, put_dropping_oldest

if TYPE_CHECKING:
    import asyncio

    from .face_support import AsyncSupport
    from .servo import ServoLoop

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

T = TypeVar("T")

log = logging.getLogger(__name__)


def _named(name: str, call: Callable[[], T]) -> T:
    """``call()``, with a refusal for an unreferenced axis or an obstacle named after the command the user
    called: a backend raises them from the primitive it was in (a grasp's opening move is ``_move``), and
    "call home() before move" after a ``grasp()`` sends the user looking in the wrong place."""
    try:
        return call()
    except (NotReferenced, MotionBlocked) as exc:
        if exc.command == name:
            raise
        raise exc.renamed(name) from exc


class Gripper(ServoFace, OptionalFeatures, ConnectionHooks, ABC):
    """A gripper in SI units (m, m/s, N, A). Open one with :func:`grippers.open`.

    Every value is checked against the profile's limits before anything is sent (``LimitError``, also a
    ``ValueError``); every wait has a timeout (``GripperTimeout``, also a ``TimeoutError``); ``state()`` may
    be called from any thread at any time, also while a motion runs. One motion runs at a time and the newer
    one wins; a motion ended early raises ``CommandFailed`` "superseded by …" or "aborted by …", and Ctrl-C
    stops the gripper before it leaves a blocking call (grippers/motions.py).
    """

    capabilities: frozenset[Capability] = frozenset()

    def __init__(self, profile: ProfileBase, url: str, *, timeout: float) -> None:
        self.profile = profile
        self.url = url
        self.timeout = timeout
        self.limits = profile.limits()
        self._fast_stopped = False
        self._faults_logged: tuple[str, ...] = ()  # what state() last logged (INFO, issue 22 §3)
        self._closed = False
        self._lock = threading.Lock()
        self._motions = MotionSupervisor(
            self._lock,
            device=lambda: self.name,
            check_open=self._check_open,
            is_closed=lambda: self._closed,
            stop=lambda: self._stop(),
            supersede=lambda: self._supersede(),
            settle_time=self._settle_time,
        )
        self._streams: list[StateStream] = []
        self._on_close: list[Callable[[], None]] = []
        # The in-process simulator behind a sim:// gripper, for tests and demos (its model and fault hooks are
        # the family's own: grippers.drivers.wsg.sim, grippers.drivers.stepfoc.sim).
        self.simulator: Any = None
        self._servo_loop: ServoLoop | None = None  # while servoing (grippers/servo.py)
        self._last_servo_loop: ServoLoop | None = None  # its counters stay readable after it ended
        self._watch: Watch | None = None  # when opened with reconnect=true (grippers/reconnect.py)
        self._opened_identity: dict[str, str] = {}  # _identity() when reconnection was switched on

    # -- what a backend provides (device units are its business) -------------------------------------------

    @property
    @abstractmethod
    def driver(self) -> Any:
        """The vendor client underneath, for vendor extras the common interface does not cover."""

    @abstractmethod
    def _home(self, timeout: float) -> None: ...

    @abstractmethod
    def _move(self, width: float, speed: float, timeout: float) -> MotionResult: ...

    @abstractmethod
    def _grasp(self, width: float, speed: float, force: float, timeout: float) -> GraspResult: ...

    @abstractmethod
    def _release(self, width: float, speed: float, timeout: float) -> MotionResult: ...

    @abstractmethod
    def _stop(self) -> None: ...

    @abstractmethod
    def _fast_stop(self) -> None: ...

    @abstractmethod
    def _acknowledge(self) -> None: ...

    @abstractmethod
    def _state(self) -> GripperState: ...

    @abstractmethod
    def _info(self) -> DeviceInfo: ...

    @abstractmethod
    def _close(self) -> None: ...

    def _abandon(self, thread_ident: int) -> None:
        """Give up the call thread ``thread_ident`` runs in the driver (its caller stopped waiting: an asyncio
        task cancelled, grippers/aio.py, through :meth:`async_support`): its waits end at once, as timeouts,
        until :meth:`_resume`, so the connection serves the next call at once. Default: nothing (the call
        runs into its own timeout)."""

    def _resume(self, thread_ident: int) -> None:
        """Thread ``thread_ident`` starts a new call: undo :meth:`_abandon`. Default: nothing."""

    def _read_on(self, loop: asyncio.AbstractEventLoop) -> Callable[[], None] | None:
        """Let the running asyncio ``loop`` read the transport itself, so that :meth:`_start_state`'s reply
        reaches its task with no thread hand-over; returns what undoes it (called on the loop's thread before
        the gripper closes), or None where the driver keeps its reader thread (the default).

        Why only some: an event loop can wait only on a file descriptor (a SocketCAN or ``udp_multicast`` bus;
        drivers/stepfoc/can_reader.py)."""
        return None

    def _start_state(self, done: StateCallback) -> StartedRead | None:
        """Start reading the state without blocking the caller; ``done(state, None)`` or ``done(None, error)``
        is called once, from whichever thread completes it (the transport's reader, usually).

        Why: the asyncio face awaits a read the driver completes from its reader, with no worker thread and
        no thread hop on the way out (issue 20 §2). A backend that cannot returns None (the default), and
        the asyncio face runs :meth:`_state` on a worker instead. The caller gives the read up with
        :meth:`StartedRead.cancel` when its task is cancelled or :attr:`StartedRead.timeout` passed (unless
        the driver keeps the time itself); the driver then treats the exchange as timed out, as Ctrl-C leaves
        it, so the next call goes out at once.
        """
        return None

    def _default_release_width(self) -> float:
        """Where release() goes without a width: fully open, away from a part gripped from outside."""
        return self.limits.max_width

    def _motion_timeout(self, distance: float, speed: float) -> float:
        """A bound on a motion's duration when the caller gives none: twice the travel time plus slack."""
        return 2.0 * distance / max(speed, 1e-6) + 2.0 + self.timeout

    # -- the interface -----------------------------------------------------------------------------------

    @property
    def name(self) -> str:
        """``PROFILE@URL``: how errors and logs name this gripper."""
        return f"{self.profile.name}@{self.url}"

    def _check_open(self, command: str) -> None:
        if self._closed:
            raise GripperError("the gripper is closed", device=self.name, command=command)
        if self._watch is not None:
            self._watch.check(command)  # during an outage: ConnectionLost at once, nothing waits

    def _check_motion(self, command: str) -> None:
        self._check_open(command)
        if command != "servo" and self._servo_loop is not None:
            self._end_servo(stop_device=True)  # a motion command takes over from servoing
        if self._fast_stopped:
            raise FastStopActive(
                "fast stop is active: call acknowledge() before moving", device=self.name, command=command
            )

    # -- motions: one at a time, the newest wins (grippers/motions.py states the rule) -------------------

    def _settle_time(self) -> float:
        """How long a stop and the end of the motion it stops may take: two exchanges and some slack."""
        return 2.0 * self.timeout + 1.0

    def _supersede(self) -> None:
        """End the running motion on the device before a newer one is sent. A stop, by default: the WSG
        refuses a motion while one runs (E_ALREADY_RUNNING, WSG manual 4.0.x §3.2.2); a backend whose device
        takes a new target mid-motion may override this to do nothing."""
        self._stop()

    def _run_motion(
        self, name: str, call: Callable[[], T], wait: bool, *, timeout: float = 0.0, what: str = ""
    ) -> T | MotionHandle[T]:
        """Run a backend motion under the one rule (grippers/motions.py): supersede, abort, Ctrl-C stops."""
        return self._motions.run(name, lambda: _named(name, call), wait, timeout=timeout, what=what)

    def home(self, timeout: float | None = None, *, wait: bool = True) -> None | MotionHandle[None]:
        """Reference the axis (WSG homing) or calibrate the stroke (MSG); blocks until done."""
        self._check_motion("home")
        t = self._timeout(timeout, "home", self._motion_timeout(2 * self.limits.stroke, 0.02))
        return self._run_motion("home", lambda: self._home(t), wait, timeout=t)

    def _timeout(self, timeout: float | None, command: str, default: float) -> float:
        seconds = wait_seconds(timeout, command, self.name)
        if seconds is None or seconds >= threading.TIMEOUT_MAX / 4:
            return default if seconds is None else threading.TIMEOUT_MAX / 4
        return seconds

    def move(
        self, width: float, speed: float | None = None, *, wait: bool = True, timeout: float | None = None
    ) -> MotionResult | MotionHandle[MotionResult]:
        """Move the fingers to ``width`` (m) at ``speed`` (m/s; default from the profile)."""
        w, s = self._width(width, "move"), self._speed(speed, "move")
        self._check_motion("move")
        t = self._timeout(timeout, "move", self._motion_timeout(self.limits.stroke, s))
        return self._run_motion(
            "move", lambda: self._move(w, s, t), wait, timeout=t, what=f" to {w * 1000:g} mm"
        )

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

        When the jaws are already inside the part's width (an MSG rests closed after its calibration), they
        first open to the width plus ``GRASP_CLEARANCE`` (within the limits), then grasp: closing from
        inside the part would end at once "without meeting a part". For a part gripped from inside (MSG
        ``maps.inside_grip``) the same holds the other way round.
        """
        w, s, f = self._width(width, "grasp"), self._speed(speed, "grasp"), self._force(force, "grasp")
        self._check_motion("grasp")
        t = self._timeout(timeout, "grasp", self._motion_timeout(self.limits.stroke, s))
        return self._run_motion(
            "grasp",
            lambda: self._grasp_with_room(w, s, f, t),
            wait,
            timeout=2 * t,
            what=f" {w * 1000:g} mm",
        )

    GRASP_CLEARANCE = 0.005  # m: where grasp() opens to when the jaws start inside the part's width

    def _grips_from_inside(self) -> bool:
        """Whether a grasp opens onto the part; a backend whose device can grip from inside says so."""
        return False

    def _grasp_with_room(self, width: float, speed: float, force: float, timeout: float) -> GraspResult:
        try:
            now = self._state().width
        except GripperError as exc:  # the grasp itself will report a device that does not answer
            log.debug("%s: no state before the grasp: %s", self.name, exc)
            now = None
        if now is not None:
            inside = self._grips_from_inside()
            if inside and now > width:
                self._move(max(width - self.GRASP_CLEARANCE, self.limits.min_width), speed, timeout)
            elif not inside and now < width:
                self._move(min(width + self.GRASP_CLEARANCE, self.limits.max_width), speed, timeout)
            handle = self._motions.current()
            if handle is not None:
                self._motions.may_send(handle)  # stopped while opening: do not grasp after all
        return self._grasp(width, speed, force, timeout)

    def release(
        self,
        width: float | None = None,
        speed: float | None = None,
        *,
        wait: bool = True,
        timeout: float | None = None,
    ) -> MotionResult | MotionHandle[MotionResult]:
        """Open to ``width`` (m; default fully open) and end a grasp."""
        w = self._default_release_width() if width is None else self._width(width, "release")
        s = self._speed(speed, "release")
        self._check_motion("release")
        t = self._timeout(timeout, "release", self._motion_timeout(self.limits.stroke, s))
        return self._run_motion(
            "release", lambda: self._release(w, s, t), wait, timeout=t, what=f" to {w * 1000:g} mm"
        )

    def stop(self) -> None:
        """Stop the fingers where they are; a running motion raises CommandFailed "aborted by stop()".

        The WSG keeps its motor on; the MSG clears its action bit (CAN) or, having no other way over UART,
        deactivates the motor, so a held part is no longer squeezed."""
        self._check_open("stop")
        self._end_servo(stop_device=False)  # stop() ends servoing; the stop below halts its motion
        self._motions.abort("stop()")

    def fast_stop(self) -> None:
        """Stop at once; further motion is refused until :meth:`acknowledge`. A running motion raises
        CommandFailed "aborted by fast_stop()"."""
        self._check_open("fast_stop")
        self._end_servo(stop_device=False)
        # Refuse motion from here on, even if the reply is lost or another thread starts a move meanwhile:
        # the user asked for a stop, and acknowledge() is the one way out.
        self._fast_stopped = True
        self._motions.abort("fast_stop()", device_stop=self._fast_stop)

    def acknowledge(self) -> None:
        """Clear a fast stop (WSG 24h; MSG: estop bit cleared, then the error)."""
        self._check_open("acknowledge")
        self._acknowledge()
        self._fast_stopped = False

    def state(self) -> GripperState:
        """The jaws now: width (m), speed, force or current, grasp state, faults; readable during a motion.

        Raises:
            GripperTimeout: the device did not answer within the connection's timeout.
            ConnectionLost: the link is down (with ``reconnect=true``: at once during an outage).
            ProtocolError: the answer was malformed (the device or the line is not what the profile says).
            GripperError: the gripper was closed.
        """
        self._check_open("state")
        return self._took_state(self._state())

    def _took_state(self, st: GripperState) -> GripperState:
        """What every face does with a state read (threaded, asyncio): one rule in one place."""
        # The device is the truth: a fast stop raised or acknowledged elsewhere (another program, the web
        # interface, the vendor extras in .driver) is taken over here.
        self._fast_stopped = st.fast_stopped
        if st.faults != self._faults_logged:  # a fault raised or cleared: said once, at INFO
            self._faults_logged = st.faults
            log.info("%s: faults: %s", self.name, ", ".join(st.faults) or "none")
        return st

    def async_support(self) -> AsyncSupport:
        """The one declared hook of a face built on this gripper (grippers/aio.py; the CLI's commands that
        poll a motion): the non-blocking state read, giving up a cancelled call, the loop as reader, motions
        on the face's threads, stopping the motions a face started without waiting (grippers/face_support.py).
        Not a command (grippers/commands.py's ``FACE_HOOKS``)."""
        from .face_support import AsyncSupport

        return AsyncSupport(self)

    def info(self) -> DeviceInfo:
        """What the device is: vendor, model, profile, firmware, serial number and the limits in force.

        ``extra["warnings"]`` lists what the library assumed (an MSG's model opened without a profile) or
        ignored (device limits that are not finite).

        Raises:
            GripperTimeout: the device did not answer within the connection's timeout.
            ConnectionLost: the link is down.
            ProtocolError: an answer was malformed.
            GripperError: the gripper was closed.
        """
        self._check_open("info")
        return self._info()

    def stream(
        self, rate_hz: float = 50.0, callback: Callable[[GripperState], Any] | None = None
    ) -> StateStream:
        """States at ``rate_hz``; an iterator, or calls ``callback`` from a background thread. Close it."""
        with self._lock:  # registered atomically with the closed check, so close() stops every stream
            self._check_open("stream")
            read: Callable[[], GripperState] = self._state
            if self._watch is not None:  # reconnect=true: the stream pauses over an outage and marks the gap
                holder: list[StateStream] = []
                read = self._watch.stream_reader(read, lambda: bool(holder) and holder[0]._stop.is_set())
            s = StateStream(read, rate_hz, callback, on_close=self._forget_stream)
            if self._watch is not None:
                holder.append(s)
            self._streams.append(s)
        return s

    def _forget_stream(self, s: StateStream) -> None:
        with self._lock:
            if s in self._streams:
                self._streams.remove(s)

    def close(self) -> None:
        """Close the connection: stop streams, let running motions end (bounded), release the transport.
        Idempotent.

        It does not move the jaws: in Robotiq's and ur_rtde's vocabulary ``close()`` closes the gripper, here
        it ends the session, and the next call raises "the gripper is closed". To close the jaws on a part,
        :meth:`grasp`; to a width, :meth:`move` (docs/api.md, "Vocabulary").

        Marked closed first, under the lock: a second close() (another thread, atexit) returns at once, no
        stream or handle is registered behind our back, and a backend's motion wait that polls (MSG) sees
        ``_closed`` and ends instead of polling a closed link until its motion timeout.
        """
        with self._lock:
            if self._closed:
                return
            self._closed = True
            streams, self._streams = list(self._streams), []
            handles = self._motions.take_all()
            servo, self._servo_loop = self._servo_loop, None
            link, self._watch = self._watch, None
        if servo is not None:
            servo.end(self.timeout + 1.0)
        if link is not None:
            link.close()
        for s in streams:
            s.close()
        try:
            self._close()
        finally:
            for h in handles:
                h.join(5.0)
            for fn in reversed(self._on_close):
                fn()

    def __enter__(self) -> Gripper:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()

    def __repr__(self) -> str:
        return f"<{type(self).__name__} {self.name}{' closed' if self._closed else ''}>"
