"""The device contract: what a family implements so that :class:`~grippers.gripper.Gripper` can drive it.

Modelled on python-can's ``BusABC`` (a backend writes a few primitives, the base gives every user-facing
behaviour once) and on bleak's client holding a backend: the user holds a :class:`~grippers.gripper.Gripper`,
the gripper holds a :class:`Device`. A device speaks SI units (m, m/s, N, A) and its own wire protocol; it
does *not* check limits, apply defaults, run the motion rule (newer wins, cancel, Ctrl-C), keep streams or
latch fast stops: the gripper does all that, the same for every family, before and around the device's
primitives.

Required: :meth:`Device.home`, :meth:`Device.move`, :meth:`Device.grasp`, :meth:`Device.stop`,
:meth:`Device.read_state`, :meth:`Device.info`, :meth:`Device.close`. Everything else has a default that
fits a simple device. Optional features are objects the device offers or leaves ``None``
(:attr:`Device.reconnection`, :attr:`Device.servo`, :attr:`Device.soft_limits`, :attr:`Device.temperature`,
:attr:`Device.device_tag`, :attr:`Device.liveness`, :attr:`Device.state_source`), not methods to override.

The calls a device receives:

* the motion primitives run in a worker thread, one at a time, and block until the motion ended: return the
  outcome, raise ``CommandFailed`` for an end the device reports (a fault, a stop from another program),
  ``GripperTimeout`` when ``timeout`` passed;
* :meth:`Device.stop` / :meth:`Device.fast_stop` come from another thread while a motion primitive blocks:
  the primitive must then end soon (raise anything; the gripper reports the motion "aborted by stop()");
  :class:`grippers.kit.MotionEpochs` is the ready-made way for a primitive that polls for its end;
* :meth:`Device.read_state` may come from any thread at any time, also while a motion runs.

docs/backends.md has the whole contract and a worked plugin.
"""

from __future__ import annotations

from abc import ABC, abstractmethod
from collections.abc import Callable
from dataclasses import dataclass
from typing import TYPE_CHECKING, Any, Protocol, runtime_checkable

from .profile_model import Limits
from .states import Capability, DeviceInfo, GraspResult, GripperState, MotionResult

if TYPE_CHECKING:
    import asyncio

    from .errors import GripperError
    from .servo import ServoTarget

__all__ = [
    "Device",
    "DeviceContext",
    "DeviceTag",
    "Liveness",
    "Reconnection",
    "Servo",
    "SoftLimits",
    "StartedRead",
    "StateCallback",
    "StateSource",
    "StateStreamLike",
    "Temperature",
]

StateCallback = Callable[["GripperState | None", "BaseException | None"], None]


@dataclass(frozen=True)
class StartedRead:
    """A read a device started without blocking (:meth:`Device.start_read`)."""

    cancel: Callable[[], None]
    """Give the read up (task cancelled, or :attr:`timeout` passed): its exchanges are abandoned as Ctrl-C
    abandons them; ``done`` may still be called once, and is then ignored. Idempotent; never blocks."""
    timeout: float | None
    """Seconds after which the caller gives up with GripperTimeout; None: the driver times the read out
    itself (``done`` gets its GripperTimeout), and the caller arms no timer of its own."""
    command: str = "state"
    """The device command named in that timeout's message."""


@dataclass(frozen=True)
class DeviceContext:
    """What the gripper tells its device when it takes it (:meth:`Device.bind`).

    ``name`` is how errors name the gripper (``PROFILE@URL``); ``closed()`` turns True when the gripper
    closes (a polling wait ends instead of polling a closed link); ``check_same_device(identity)`` raises
    ``DeviceMismatch`` when a reconnection found another device than the opened one; ``reconnects()`` is
    True when the gripper was opened with ``reconnect=true`` (a lost link is then an outage its watch brings
    back through :attr:`Device.reconnection`, not the end).
    """

    name: str
    closed: Callable[[], bool] = lambda: False
    check_same_device: Callable[[dict[str, str]], None] = lambda identity: None
    reconnects: Callable[[], bool] = lambda: False


# -- optional features: objects a device offers, or None --------------------------------------------------


@runtime_checkable
class Reconnection(Protocol):
    """Re-establishing a lost link (``reconnect=true``; grippers/reconnect.py watches and calls these)."""

    def alive(self) -> bool:
        """Cheap, no traffic: whether the driver has noticed its link is gone (False) or not."""
        ...

    def identity(self) -> dict[str, str]:
        """What tells this device from another of its family (model, serial), read without traffic where
        possible; recorded when reconnection is switched on. Empty: devices cannot be told apart."""
        ...

    def reconnect(self) -> None:
        """Open a fresh link on the same URL, check it reaches the same device
        (:attr:`DeviceContext.check_same_device`) and swap it in; a GripperError while the device is not
        back."""
        ...


@runtime_checkable
class Servo(Protocol):
    """Streaming targets without waiting for each motion's end (``Gripper.servo``)."""

    def begin(self) -> None:
        """Before the first target of a servoing: leave the device ready to take targets."""
        ...

    def send(self, target: ServoTarget) -> bool | None:
        """Put one target on the wire without waiting for the motion; False if nothing needed sending (the
        same target again), None if unknown."""
        ...

    def end(self) -> None:
        """Servoing ended for another motion command: leave the device ready to take it."""
        ...


@runtime_checkable
class SoftLimits(Protocol):
    """Limits the device itself enforces on finger motion (m); ``None, None`` clears them."""

    def set(self, min_width: float | None, max_width: float | None) -> None: ...


@runtime_checkable
class Temperature(Protocol):
    def read(self) -> float:
        """The gripper's (or its driver's) temperature in °C."""
        ...


@runtime_checkable
class DeviceTag(Protocol):
    def read(self) -> str:
        """The user-defined name stored in the device."""
        ...

    def write(self, tag: str) -> None: ...


@runtime_checkable
class Liveness(Protocol):
    """A link whose loss the device learns by itself, without a read failing (a served gripper: the
    server's liveliness token went away). ``Gripper.connected``/``on_connection`` follow it, and every call
    raises ConnectionLost at once once it is lost (final without ``reconnect=true``)."""

    @property
    def error(self) -> GripperError | None:
        """Why the link is lost for good; None while it is up."""
        ...

    def add_listener(self, callback: Callable[[bool], Any]) -> Callable[[], None]:
        """Call ``callback(False)`` once, from a thread of the device's, when the link is lost; returns what
        unregisters it."""
        ...


class StateStreamLike(Protocol):
    """What ``Gripper.stream()`` returns: iterate, ``get(timeout)``, ``close()`` (grippers/streams.py)."""

    def get(self, timeout: float | None = None) -> GripperState: ...

    def close(self) -> None: ...


@runtime_checkable
class StateSource(Protocol):
    """States the device pushes (a subscription) instead of the gripper polling :meth:`Device.read_state`."""

    def subscribe(
        self,
        rate_hz: float,
        callback: Callable[[GripperState], Any] | None,
        on_close: Callable[[Any], None],
    ) -> StateStreamLike:
        """A stream of at most ``rate_hz`` states a second (a ``grippers.streams.QueuedStream``); it calls
        ``on_close(stream)`` once when closed."""
        ...


# -- the device ----------------------------------------------------------------------------------------


class Device(ABC):
    """One gripper of a family in SI units; held by a :class:`~grippers.gripper.Gripper`.

    Class attributes a device sets: :attr:`capabilities` (what ``Gripper.require`` checks),
    :attr:`reports_fast_stop` (whether :meth:`read_state` reports a fast stop the device latches itself),
    :attr:`grips_from_inside`, :attr:`moves_to_new_targets`.
    """

    capabilities: frozenset[Capability] = frozenset()

    reports_fast_stop: bool = False
    """True when the device latches a fast stop itself and ``read_state().fast_stopped`` says so (the WSG's
    SF_FAST_STOP): the gripper then takes the device's word, also for a fast stop raised or cleared by
    another program. False (the default): the gripper keeps the latch itself until ``acknowledge()`` and
    adds ``"fast_stop"`` to the states' faults (a Robotiq has no fast-stop state of its own)."""

    grips_from_inside: bool = False
    """Whether a grasp opens onto the part (an MSG with ``maps.inside_grip``)."""

    moves_to_new_targets: bool = False
    """True when the device takes a new target mid-motion (Robotiq rPR rewritten with rGTO set): the gripper
    then does not stop the device between a motion and the newer one that supersedes it (it calls
    :meth:`supersede`); False: it calls :meth:`stop` first (the WSG refuses a motion while one runs,
    E_ALREADY_RUNNING, WSG manual 4.0.x §3.2.2)."""

    profile_assumed: bool = False
    """True when the device cannot report its model and none was named, so the profile is a guess (an MSG
    cannot report its rail length): ``grippers.open`` then warns with ``ProfileAssumed``."""

    fast_stop_shared: bool = False
    """True when other clients share the device and may acknowledge its fast stop (a served gripper): a
    latched gripper reads the state before it refuses a motion, and takes the device's word."""

    reconnection: Reconnection | None = None
    servo: Servo | None = None
    soft_limits: SoftLimits | None = None
    temperature: Temperature | None = None
    device_tag: DeviceTag | None = None
    liveness: Liveness | None = None
    state_source: StateSource | None = None

    context: DeviceContext = DeviceContext(name="?")

    def bind(self, context: DeviceContext) -> None:
        """Called once by the gripper that takes this device, before any other call."""
        self.context = context

    @property
    def name(self) -> str:
        """How errors name this gripper (``PROFILE@URL``)."""
        return self.context.name

    @property
    def driver(self) -> Any:
        """The vendor client underneath, for vendor extras the common interface does not cover."""
        return None

    # -- required primitives ----------------------------------------------------------------------------

    @abstractmethod
    def home(self, timeout: float) -> None:
        """Reference, calibrate or activate the axis; return when the device is ready for motions."""

    @abstractmethod
    def move(self, width: float, speed: float, timeout: float) -> MotionResult:
        """Move the jaws to ``width`` (m) at ``speed`` (m/s), checked by the gripper already."""

    @abstractmethod
    def grasp(self, width: float, speed: float, force: float, timeout: float) -> GraspResult:
        """Close on a part of nominal ``width`` with ``force`` (N); ``grasped`` says if it is held."""

    def release(self, width: float, speed: float, timeout: float) -> MotionResult:
        """Open to ``width`` and end a grasp; by default a :meth:`move`."""
        return self.move(width, speed, timeout)

    @abstractmethod
    def stop(self) -> None:
        """Stop the jaws where they are; a blocked motion primitive must end soon after."""

    def fast_stop(self) -> None:
        """Stop at once (the device's emergency stop where it has one); by default :meth:`stop`. The gripper
        refuses motion until ``acknowledge()`` either way."""
        self.stop()

    def acknowledge(self) -> None:
        """Clear a fast stop or a fault so the device takes motions again; by default nothing."""
        return None

    def fast_stop_latched(self) -> bool:
        """For a device that :attr:`reports_fast_stop`: whether a fast stop is latched now (one cheap read).
        The gripper asks at open and after a reconnection, so motions are refused with FastStopActive from
        the start (a WSG left in FAST STOP by a TCP connection dropped without 07h, manual 4.0.x §1.4.2).
        Default: False (nothing latched, no traffic)."""
        return False

    def supersede(self) -> None:
        """End the running motion before a newer one is sent: :meth:`stop` by default; nothing to send for a
        device that :attr:`moves_to_new_targets` (its blocked primitive must still end, e.g. a new
        :class:`grippers.kit.MotionEpochs` epoch)."""
        self.stop()

    @abstractmethod
    def read_state(self) -> GripperState:
        """The jaws now; called from any thread, also while a motion runs."""

    @abstractmethod
    def info(self) -> DeviceInfo:
        """What the device is (vendor, model, firmware, serial, the limits in force)."""

    @abstractmethod
    def close(self) -> None:
        """Release the transport; the gripper has ended motions, streams and servoing before."""

    # -- optional hooks with defaults -------------------------------------------------------------------

    def narrow_limits(self, limits: Limits) -> Limits:
        """The limits the gripper enforces, given the profile's: narrow them where the device can do less
        (an MSG's force is a current limit: the forces its current range gives). The profile's by default."""
        return limits

    def motion_timeout(self, default: float) -> float:
        """The bound on a motion the caller gave no timeout for; ``default`` is twice the travel time plus
        slack. A device whose referencing takes longer (an MSG's calibration may run twice) raises it."""
        return default

    def settle_time(self, timeout: float) -> float:
        """How long a stop and the end of the motion it stops may take (``timeout`` is the exchange
        timeout): two exchanges and some slack by default."""
        return 2.0 * timeout + 1.0

    def default_release_width(self, max_width: float, min_width: float) -> float:
        """Where ``release()`` goes without a width: fully open by default."""
        return min_width if self.grips_from_inside else max_width

    def start_read(self, done: StateCallback) -> StartedRead | None:
        """Start a state read without blocking: ``done(state, None)`` or ``done(None, error)`` once, from
        any thread. For the asyncio face, which then awaits the reply with no worker thread. None (the
        default): the asyncio face runs :meth:`read_state` on a worker."""
        return None

    def abandon(self, thread_ident: int) -> None:
        """The caller of thread ``thread_ident``'s call stopped waiting (an asyncio task cancelled): end its
        waits at once, as timeouts, until :meth:`resume`. Default: nothing (the call runs into its
        timeout)."""
        return None

    def resume(self, thread_ident: int) -> None:
        """Thread ``thread_ident`` starts a new call: undo :meth:`abandon`."""
        return None

    def read_on(self, loop: asyncio.AbstractEventLoop) -> Callable[[], None] | None:
        """Let the running asyncio ``loop`` read the transport itself (only where the loop can wait on a file
        descriptor); returns what undoes it. None (the default): the driver keeps its reader."""
        return None
