"""The one declared seam a face on an event loop uses: ``Gripper.async_support()`` (issue 32 §3).

Why: the asyncio face (grippers/aio.py) needs a few things a blocking caller never does: a state read the
driver completes from its reader (no worker thread), giving up a call a cancelled task left running in a
worker, letting the loop read a transport that has a file descriptor, and running motions on its own pool
of threads. It used to reach into the gripper's private members for them; this object names them once, so
the gripper's internals can change without breaking a face, and a face written outside the library (trio,
a GUI's loop) has a documented door instead of private ones.

What it offers is the gripper's own rules, not copies: each member calls the hook the gripper's
:class:`~grippers.device.Device` implements (``start_read``/``abandon``/``resume``/``read_on``) or applies
the rule the threaded call applies (``took_state``: the fast-stop latch and the fault log of
``Gripper.state()``).
"""

from __future__ import annotations

from collections.abc import Callable
from typing import TYPE_CHECKING, Protocol

if TYPE_CHECKING:
    import asyncio

    from .connection import Watch
    from .device import Device, StartedRead, StateCallback
    from .motions import MotionSupervisor, Spawn
    from .states import GripperState


class GripperCore(Protocol):
    """The members of :class:`~grippers.gripper.Gripper` this seam wraps; declared here, not imported from
    gripper.py, which imports this module (no import circle: docs/DEVELOPING.md, rule 1)."""

    device: Device
    _closed: bool
    _motions: MotionSupervisor

    @property
    def servoing(self) -> bool: ...

    @property
    def link_watch(self) -> Watch | None: ...

    def _check_open(self, command: str) -> None: ...

    def _took_state(self, st: GripperState) -> GripperState: ...

    def _motion_timeout(self, distance: float, speed: float) -> float: ...


class AsyncSupport:
    """What a gripper offers a face that awaits instead of blocking. Get it with ``g.async_support()``."""

    __slots__ = ("_g",)

    def __init__(self, gripper: GripperCore) -> None:
        self._g = gripper

    # -- the state read -------------------------------------------------------------------------------------

    def start_state(self, done: StateCallback) -> StartedRead | None:
        """Start a state read without blocking: ``done(state, None)`` or ``done(None, error)`` is called
        once, from whichever thread completes it; None where the backend reads only by blocking (then run
        ``g.state()`` on a worker). Refused at once on a closed gripper or during an outage, as
        ``state()``. Pass the state it delivers through :meth:`took_state`; give the read up with
        :meth:`StartedRead.cancel` when the awaiting task is cancelled or its timeout passed."""
        g = self._g
        g._check_open("state")
        return g.device.start_read(done)

    def took_state(self, state: GripperState) -> GripperState:
        """What ``Gripper.state()`` does with every reading (the fast-stop latch follows the device, a
        changed fault set is logged once): apply it to a state :meth:`start_state` delivered."""
        return self._g._took_state(state)

    # -- giving up a call -----------------------------------------------------------------------------------

    def abandon(self, thread_ident: int) -> None:
        """The call thread ``thread_ident`` runs in the driver lost its caller (an asyncio task was
        cancelled): its waits end at once, as timeouts, until :meth:`resume`, so the next call goes out at
        once. Does nothing on a backend that cannot (the call then ends by its own timeout)."""
        self._g.device.abandon(thread_ident)

    def resume(self, thread_ident: int) -> None:
        """Thread ``thread_ident`` starts a new call: undo :meth:`abandon`."""
        self._g.device.resume(thread_ident)

    # -- the event loop as the reader -----------------------------------------------------------------------

    def read_on(self, loop: asyncio.AbstractEventLoop) -> Callable[[], None] | None:
        """Let ``loop`` read the transport itself (a SocketCAN or ``udp_multicast`` bus: a file descriptor),
        so a reply reaches its task with no thread hand-over; returns what undoes it (call it on the loop's
        thread before the gripper closes), or None where the driver keeps its reader thread."""
        return self._g.device.read_on(loop)

    # -- motions --------------------------------------------------------------------------------------------

    def run_motions_with(self, spawn: Spawn | None) -> None:
        """Run every motion's blocking backend call through ``spawn(body, name)`` (a face's fixed pool of
        threads) instead of a thread of its own each; None goes back to a thread each. The motion rule
        (supersede, abort, the handles) stays the gripper's (grippers/motions.py)."""
        self._g._motions.spawn = spawn

    def stop_running_motions(self, by: str) -> list[BaseException]:
        """Stop (bounded) every motion still running, each ending with CommandFailed "aborted by BY"; returns
        the stops that failed. Sends nothing when no motion runs (an MSG over UART stops by switching its
        motor off, which would let a held part go).

        Why a face needs it: the gripper stops a motion on Ctrl-C only inside a blocking call; a motion
        started with ``wait=False`` belongs to its caller, so a command that polls one (the CLI's
        ``selftest``, ``record --do``) stops it itself when it is interrupted (issue 33 §1)."""
        supervisor = self._g._motions
        failures = []
        for handle in list(supervisor.handles):
            if handle.done():
                continue
            failure = supervisor.abort(by, handle, bounded=True)
            if failure is not None:
                failures.append(failure)
        return failures

    def motion_timeout(self, distance: float, speed: float) -> float:
        """The bound the gripper puts on a motion of ``distance`` (m) at ``speed`` (m/s) when the caller
        gives none (a face that times a motion itself uses the same bound)."""
        return self._g._motion_timeout(distance, speed)

    # -- what a face asks before choosing its path ----------------------------------------------------------

    @property
    def closed(self) -> bool:
        """close() was called (``connected`` is also False during an outage; this is not)."""
        return self._g._closed

    @property
    def servoing(self) -> bool:
        """A servoing runs: a further target is queued without waiting (``servo()``), the first one of a
        servoing supersedes the running motion and may wait for it."""
        return self._g.servoing

    @property
    def reconnects(self) -> bool:
        """Opened with ``reconnect=true``: a lost link is an outage to wait out, not the end."""
        return self._g.link_watch is not None
