"""MSG grippers on STEPFOC drivers over any python-can bus: one reader per bus, one handle per node.

Several grippers share one CAN bus, so :class:`StepfocBus` owns the bus and ONE reader thread that reads
every frame and hands it to whoever waits for it. What a frame means (which request it answers, another
host's traffic, a heartbeat, a second device on one node id) is decided by the sans-IO
:class:`~grippers.drivers.stepfoc.can_session.CanSession`, which the bus calls under its lock; the bus keeps
the threads, the locks, the requests in flight and the python-can bus. :class:`StepfocNode` is the
per-gripper API.

A reply is matched by (node, command) only (the protocol has no sequence numbers), so at most one request per
(node, command) is on the wire at a time: a second one queues and goes out when the first ends. Different
nodes, or different commands of one node, run concurrently from different threads. A request either blocks
its thread (:meth:`StepfocBus.request`) or reports to a callback from the reader
(:meth:`StepfocBus.start_request`, which the asyncio face awaits with no thread); both are one
:class:`PendingRequest`, started, matched and ended the same way.

A caller that stops waiting from another thread (an asyncio task cancelled: grippers/aio.py) gives its thread
up with :meth:`StepfocBus.abandon` (a started request: :meth:`PendingRequest.cancel`): the request ends at
once with GripperTimeout and its (node, command) key is free for the next request, which goes out at once.
Nothing more is needed: with no sequence number there is nothing to prove lost, and a late reply to the
abandoned request is a reply of the same kind as the next one's (drivers/stepfoc/can_session.py).

Two devices with one node id answer every request twice: the session notices (can_session.py), and every
later request to that node raises :class:`ProtocolError` naming it, instead of returning the states of two
devices in turn.
"""

from __future__ import annotations

import logging
import operator
import threading
import time
from collections import deque
from collections.abc import Callable
from typing import TYPE_CHECKING, Any, Generic, Protocol, TypeVar, overload

import can

from ..canlink import describe_failure, open_bus, standard_message
from ..closing import Closing
from ..errors import (
    CommandFailed,
    ConnectionLost,
    GripperError,
    GripperTimeout,
    LimitError,
    ProtocolError,
)
from . import can_waits
from .can_protocol import (
    COMMANDS,
    DEFAULT_BITRATE,
    MAX_NODE,
    CanFrame,
    Cmd,
    DeviceInfo,
    EncoderData,
    ErrorState,
    GripperCommand,
    GripperStatus,
    Message,
    encode_command,
    encode_frame,
    pack_id,
    parse_can_url,
)
from .can_reader import BusReader
from .can_session import (
    OWN_ECHO,
    CanSession,
    Delivery,
    DuplicateFound,
    Heartbeat,
    Key,
    NodeFacts,
    is_stepfoc_frame,
)
from .can_waits import CalibrationWatch
from .dissect import log_can_frame
from .motion import STALL_MIN_S, CalibrationTracker
from .node_setup import NodeSetup

__all__ = ["CalibrationWatch", "StepfocBus", "StepfocNode", "open_node", "parse_url"]

if TYPE_CHECKING:
    import asyncio

log = logging.getLogger(__name__)

_SETTLE_S = 5.0  # bound on a wait for an outcome another thread is storing (microseconds in practice)

# After a 5-byte 61 the firmware resets its at-position latch at the next control tick (160 us on STEPFOC,
# 200 us on Spectral Micro); a poll that reaches the node before that tick cancels the reset and the motion
# reports detection 3 throughout (docs/protocols.md §2). A node handle waits this long before its next poll.
LATCH_GUARD_S = 0.0005


def _status_fault(st: GripperStatus) -> tuple[str | None, list[str] | None]:
    """What a 60 alone says of the node's faults: (the answer, None), or (None, the names so far) when the
    identifier's error bit or a flag means frame 26 must be asked for the cause (StepfocNode.fault)."""
    if st.estop_error:
        return "estop", None
    names = [n for n, on in (("watchdog", st.timeout_error), ("temperature", st.temperature_error)) if on]
    if not st.error_bit and not names:
        return None, None
    return None, names


def _named_fault(names: list[str], es: ErrorState | None) -> str:
    """The fault names once frame 26 answered (``es``), or did not in time (None)."""
    if es is not None:
        if es.estop:
            return "estop"
        names = names + [n for n in es.active() if n not in names]
    return ",".join(names) or "error"


def parse_url(url: str) -> tuple[str, str, dict[str, str]]:
    """``stepfoc+can://INTERFACE/CHANNEL?node=N&bitrate=B`` -> (interface, channel, query)."""
    return parse_can_url(url)  # the one parser, shared with the simulator


def _byte(value: Any, what: str, device: str, command: str) -> int:
    try:
        v = operator.index(value)
    except TypeError:
        raise LimitError(
            f"{what} must be an integer 0..255, not {value!r}", device=device, command=command
        ) from None
    if not 0 <= v <= 255:
        raise LimitError(f"{what} {v} outside 0..255", device=device, command=command)
    return v


def _given_up(device: str, name: str) -> GripperTimeout:
    return GripperTimeout("abandoned: the caller stopped waiting", device=device, command=name)


ReplyCallback = Callable[["Message | None", "GripperError | None"], None]


def _timed_out(w: PendingRequest) -> GripperTimeout:
    """A request's timeout, in the same words whoever keeps its time (a waiting thread, the reader)."""
    if not w.sent:
        text = f"another {w.name} to this node did not finish within {w.send_timeout:g} s"
    else:
        text = f"no reply within {w.send_timeout:g} s"
    return GripperTimeout(text, device=w.device, command=w.name)


class PendingRequest:
    """One request to a (node, command) key, from start to its settling: the reply (from the reader thread),
    a failure (an unsendable frame, a failing bus, a duplicate node id, an abandoned thread) or
    :meth:`cancel`, whichever comes first; the others are ignored. Then the key goes to the next request
    queued for it. The outcome goes to ``reply`` (:meth:`StepfocBus.start_request`) or, without one, wakes
    the thread waiting in :meth:`StepfocBus.request`.

    The signals are plain locks: ``_claim`` is taken by whoever settles, ``_signal`` (taken at creation) is
    released for the waiting thread. Why not a ``threading.Event``: an Event is a Condition around a lock and
    its ``wait`` allocates another lock, about 4 us per request against 0.7 us, paid on every poll of every
    node (docs/performance.md, target 5).
    """

    __slots__ = (
        "_bus",
        "_claim",
        "_reply",
        "_signal",
        "deadline",
        "device",
        "done",
        "error",
        "frame",
        "key",
        "message",
        "name",
        "owner",
        "queued",
        "send_timeout",
        "sent",
    )

    def __init__(
        self,
        bus: StepfocBus,
        key: Key,
        frame: CanFrame,
        send_timeout: float,
        device: str,
        name: str,
        reply: ReplyCallback | None = None,
        owner: int = 0,
    ) -> None:
        self._bus = bus
        self.key = key
        self.frame = frame
        self.send_timeout = send_timeout
        self.device = device  # who and what an error names
        self.name = name
        self._reply = reply
        self.owner = owner  # the waiting thread's ident (StepfocBus.abandon finds its request by it)
        # A request nobody waits for times out by the reader (StepfocBus._expire), ``send_timeout`` after its
        # frame went out (set then): queued behind others of its key it waits its turn, as calls queued in the
        # asyncio face did, and each one out is bounded. None: not sent yet, or a thread keeps its own time.
        self.deadline: float | None = None
        self._claim = threading.Lock()
        if reply is None:  # a thread will wait: the signal it wakes on, taken until settled
            self._signal = threading.Lock()
            self._signal.acquire()
        self.done = False  # settled: later frames of this key do not overwrite the outcome
        self.queued = False  # waits for its key behind another request
        self.sent = False  # its frame went out (or was about to): a reply is expected
        self.message: Message | None = None
        self.error: GripperError | None = None

    def settle(self, message: Message | None, error: GripperError | None) -> None:
        """The outcome, once: frees the key, then tells the waiting thread or the callback, then starts the
        next request of the key (so its frame does not delay this outcome)."""
        if not self._claim.acquire(False):
            return  # settled already: answered, failed or cancelled
        self.message, self.error, self.done = message, error, True
        nxt = self._bus._finish(self)
        if self._reply is None:
            self._signal.release()
        else:
            try:
                self._reply(message, error)
            except Exception:  # noqa: BLE001 - a callback must not kill the reader
                log.exception("%s: the reply callback of %s raised", self.device, self.name)
        if nxt is not None:
            self._bus._start(nxt)

    def cancel(self) -> bool:
        """Give the request up, as :meth:`StepfocBus.abandon` gives a thread's up: its key is free at once,
        a late reply goes to nobody (module docstring), nobody is told. Idempotent; never waits for the
        device. True if this call settled it (False: it was settled already)."""
        if not self._claim.acquire(False):
            return False
        self.done = True
        nxt = self._bus._finish(self)
        if nxt is not None:
            self._bus._start(nxt)
        return True

    def wait(self, timeout: float) -> bool:
        """Block until settled (a request without a callback); False after ``timeout`` seconds."""
        return self._signal.acquire(timeout=timeout)


class StepfocBus(Closing):
    """One python-can bus shared by any number of :class:`StepfocNode` handles."""

    def __init__(
        self,
        bus: can.BusABC | None = None,
        *,
        interface: str | None = None,
        channel: str | None = None,
        bitrate: int | None = DEFAULT_BITRATE,
        device: str | None = None,
        **bus_kwargs: Any,
    ) -> None:
        self.device = device or (
            f"stepfoc+can://{interface}/{channel}" if bus is None else f"can {bus.channel_info}"
        )
        self._own_bus = bus is None
        self.channel = channel if bus is None else bus.channel_info
        self._open_args: dict[str, Any] = {}
        if bus is None:
            kwargs = dict(bus_kwargs)
            if bitrate is not None and interface not in ("virtual", "udp_multicast"):
                kwargs["bitrate"] = bitrate
            self._open_args = {"interface": interface, "channel": channel, **kwargs}
            bus = self._open_bus()
        self.bus = bus
        self._reopen_lock = threading.Lock()
        self._lock = threading.Lock()  # guards the session and the tables below
        # the protocol: which frame answers which request; udp_multicast hands our own frames back
        self._session = CanSession(self.device, echoes=type(bus).__name__ == "UdpMulticastBus")
        self._waiters: dict[Key, PendingRequest] = {}  # the request that holds each key
        self._queued: dict[Key, deque[PendingRequest]] = {}  # requests waiting for their key, in order
        self._abandoned: set[int] = set()  # threads whose caller gave up (abandon(), the module docstring)
        self._timed: set[PendingRequest] = set()  # requests answered by callback, until settled (_expire)
        self._heartbeats: dict[int, threading.Condition] = {}
        self._listeners: list[Callable[[can.Message], None]] = []
        self._error: ConnectionLost | None = None  # why the bus failed (reader or close); reopen() clears it
        self._closed = False
        self._reader = BusReader(self.device, lambda: self.bus, self._received, self._tick, self._fail)
        self._reader.start()

    def _open_bus(self) -> can.BusABC:
        try:
            return open_bus(**self._open_args)
        except (can.CanError, OSError, ValueError, ImportError) as exc:
            raise ConnectionLost(
                f"cannot open the CAN bus: {exc}", device=self.device, command="open"
            ) from exc

    def reopen(self) -> bool:
        """After the bus failed (its interface went down or away), open a fresh one and restart the reader.

        Why a fresh bus: a SocketCAN socket survives its interface going down and up, but not the interface
        being deleted and created again (drivers/canlink.py); a new socket covers both. Only a bus this
        object opened is reopened (a bus passed in belongs to the caller). Requests in flight already failed
        with ConnectionLost. Returns True if it reopened, False when there was nothing to do; raises
        ConnectionLost while the interface cannot be opened. Used by ``reconnect=true``.
        """
        with self._reopen_lock:
            if self._closed:
                raise ConnectionLost("the bus is closed", device=self.device, command="reconnect")
            if self._error is None:
                return False
            if not self._own_bus:
                raise ConnectionLost(
                    f"CAN bus failed and was passed in by the caller: {self._error}",
                    device=self.device,
                    command="reconnect",
                )
            self._reader.stop()  # it ended at the failure; wait for it to be gone
            try:
                self.bus.shutdown()
            except (can.CanError, OSError):
                pass  # the old socket may be unusable already; the new one is what matters
            self.bus = self._open_bus()
            with self._lock:
                self._session.reset()
            self._error = None
            self._reader.start()
            log.info("%s: CAN bus reopened", self.device)
            return True

    @classmethod
    def from_url(cls, url: str, **kw: Any) -> tuple[StepfocBus, int]:
        """Open the bus a ``stepfoc+can://INTERFACE/CHANNEL?node=N`` URL names; returns (bus, node)."""
        interface, channel, params = parse_url(url)
        bitrate = int(params["bitrate"]) if "bitrate" in params else DEFAULT_BITRATE
        if "port" in params:  # udp_multicast: a private port isolates a bus (groups do not, on Linux)
            kw.setdefault("port", int(params["port"]))
        return cls(interface=interface, channel=channel, bitrate=bitrate, device=url, **kw), int(
            params.get("node", 0)
        )

    # ------------------------------------------------------------------------------------------ reader

    def _received(self, msg: can.Message) -> None:
        try:
            self._dispatch(msg)
        except Exception:  # noqa: BLE001 - a frame we cannot handle must not kill the reader
            log.exception("%s: reader ignored a frame it could not handle: %r", self.device, msg)

    def _tick(self) -> None:
        if self._timed:
            self._expire(time.monotonic())

    def attach_loop(self, loop: asyncio.AbstractEventLoop) -> bool:
        """Let the running asyncio ``loop`` read this bus instead of the reader thread, while attached: a
        reply then completes an awaiting task with no thread hand-over (drivers/stepfoc/can_reader.py). Call
        on the loop's thread; False (nothing changes) for a bus without a file descriptor, or one another
        loop reads. Each True needs a :meth:`detach_loop`."""
        return self._reader.attach(loop)

    def detach_loop(self, loop: asyncio.AbstractEventLoop) -> None:
        """Undo :meth:`attach_loop` (on the loop's thread); the last one gives the bus back to a thread."""
        self._reader.detach(loop)

    def _expire(self, now: float) -> None:
        """Time out the requests nobody waits for whose deadline passed (the reader's clock: it wakes at least
        every READ_POLL_S): the outcome and the words of :meth:`request`'s own timeout."""
        with self._lock:
            late = [w for w in self._timed if w.deadline is not None and now >= w.deadline]
        for w in late:
            w.settle(None, _timed_out(w))

    def _fail(self, exc: BaseException) -> None:
        if isinstance(exc, ConnectionLost):
            self._error = exc
        else:
            self._error = ConnectionLost(describe_failure(exc, self.channel, "receive"), device=self.device)
        with self._lock:
            waiters = [*self._waiters.values(), *(w for q in self._queued.values() for w in q)]
        text = f"CAN bus failed: {self._error.message}"
        for w in waiters:
            w.settle(None, ConnectionLost(text, device=w.device, command=w.name))

    def _dispatch(self, msg: can.Message) -> None:
        for listener in list(self._listeners):
            try:
                listener(msg)
            except Exception:  # noqa: BLE001, S110 - a monitor callback must not kill the reader
                pass
        arbitration_id = msg.arbitration_id
        if not is_stepfoc_frame(arbitration_id, error_frame=msg.is_error_frame, extended=msg.is_extended_id):
            return
        now = time.monotonic()
        with self._lock:
            event = self._session.received(arbitration_id, msg.data, now=now, remote=msg.is_remote_frame)
            waiter = self._waiters.get(event.key) if type(event) is Delivery else None
        if event is not OWN_ECHO:  # our own frame was logged as it went out (send_frame)
            log_can_frame(self.device, arbitration_id, msg.data, msg.is_remote_frame, msg.timestamp)
        if waiter is not None:
            assert type(event) is Delivery
            waiter.settle(event.message, event.error)
        elif type(event) is Heartbeat:
            cond = self.heartbeat_condition(event.node)
            with cond:
                cond.notify_all()
        elif type(event) is DuplicateFound:
            log.warning("%s: %s", self.device, event.reason)

    def _facts(self, node: int) -> NodeFacts:
        with self._lock:
            return self._session.node(node)

    # ------------------------------------------------------------------------------------------ sending

    def _check_open(self, device: str, command: str) -> None:
        if self._closed:
            raise ConnectionLost("the bus is closed", device=device, command=command)
        if self._error is not None:
            raise ConnectionLost(f"CAN bus failed: {self._error.message}", device=device, command=command)

    def send_frame(
        self,
        frame: CanFrame,
        *,
        device: str | None = None,
        command: str = "send",
        timeout: float | None = 0.5,
    ) -> None:
        """Put one frame on the bus; python-can failures become ConnectionLost (the frame was not sent)."""
        device = device or self.device
        self._check_open(device, command)
        msg = standard_message(frame.arbitration_id, frame.data, frame.remote)
        if self._session.echoes:  # told before it goes: the echo may be read before send() returns
            with self._lock:
                self._session.sending(
                    frame.arbitration_id, frame.data, remote=frame.remote, now=time.monotonic()
                )
        try:
            self.bus.send(msg, timeout=timeout)
        except can.CanError as exc:
            raise ConnectionLost(
                describe_failure(exc, self.channel, "send"), device=device, command=command
            ) from exc
        log_can_frame(device, frame.arbitration_id, frame.data, frame.remote, time.time())

    def _begin(self, w: PendingRequest) -> None:
        """Put the request ``w``, which holds its key, on the wire. Raises GripperError when it may not go."""
        key = w.key
        with self._lock:
            if w.done:  # settled (cancelled, failed) while it was handed its key: nothing to send
                return
            duplicate = self._session.node(key[0]).duplicate
            if duplicate is not None:
                raise ProtocolError(duplicate, device=w.device, command=w.name)
            if self._abandoned and w.owner in self._abandoned:
                raise _given_up(w.device, w.name)
            self._session.sent(key)
            w.sent = True
            if w._reply is not None:
                w.deadline = time.monotonic() + w.send_timeout
        self.send_frame(w.frame, device=w.device, command=w.name, timeout=w.send_timeout)

    def _start(self, w: PendingRequest) -> None:
        try:
            self._begin(w)
        except GripperError as exc:
            w.settle(None, exc)

    def _finish(self, w: PendingRequest) -> PendingRequest | None:
        """``w`` was settled: forget it and hand its key to the next request queued for it, which the caller
        then starts (returned)."""
        key = w.key
        with self._lock:
            self._timed.discard(w)
            if w.queued:  # never held the key
                w.queued = False
                self._queued[key].remove(w)
                return None
            if self._waiters.get(key) is not w:
                return None
            self._session.gave_up(key)  # a late reply is expected, and goes to nobody
            queue = self._queued.get(key)
            if not queue:
                del self._waiters[key]
                return None
            nxt = self._waiters[key] = queue.popleft()
            nxt.queued = False
            return nxt

    def _submit(self, w: PendingRequest) -> PendingRequest:
        """The one way a request starts: at once if its key is free, else queued behind the request holding
        it (one request per key on the wire: the protocol's only way of matching replies)."""
        with self._lock:
            given_up = bool(self._abandoned) and w.owner in self._abandoned
            holds = not given_up and w.key not in self._waiters
            if w._reply is not None and not given_up:
                self._timed.add(w)
            if holds:
                self._waiters[w.key] = w
            elif not given_up:
                w.queued = True
                queue = self._queued.get(w.key)
                if queue is None:
                    queue = self._queued[w.key] = deque()
                queue.append(w)
        if given_up:  # its caller gave up: it ends at once, without waiting for its turn
            w.settle(None, _given_up(w.device, w.name))
        elif holds:
            self._start(w)
        return w

    def start_request(
        self,
        node: int,
        command: int,
        frame: CanFrame,
        timeout: float,
        *,
        device: str,
        name: str,
        reply: ReplyCallback,
    ) -> PendingRequest:
        """Send ``frame`` without waiting: ``reply(message, None)`` or ``reply(None, error)`` is called once,
        from the reader thread (a reply, a failed bus), from the thread that ended the request before (this
        one's turn came and its frame could not go) or from this call, unless :meth:`PendingRequest.cancel`
        came first. It times out like :meth:`request` (GripperTimeout after ``timeout`` seconds, from the
        reader, which wakes at least every READ_POLL_S). While a request of the same key is in flight, this
        one queues and goes out when that one ends; its time runs from its send."""
        return self._submit(PendingRequest(self, (node, command), frame, timeout, device, name, reply))

    def request(
        self, node: int, command: int, frame: CanFrame, timeout: float, *, device: str, name: str
    ) -> Message:
        """Send ``frame`` and wait for the reply keyed (node, command): :meth:`start_request`'s request,
        waited for by this thread (one request per key at a time; a second one waits its turn)."""
        deadline = time.monotonic() + timeout
        w = self._submit(
            PendingRequest(self, (node, command), frame, timeout, device, name, owner=threading.get_ident())
        )
        if self._reader.reads_here():  # the event loop reads this bus, and this is its thread: read here
            self._reader.pump(lambda: w.done, deadline)
        if not w.wait(max(0.0, deadline - time.monotonic())):
            if w.cancel():
                self._check_open(device, name)
                raise _timed_out(w)
            # settled just now by another thread: its outcome is stored before the signal, with no I/O
            # in between, so this wait ends at once
            if not w.wait(_SETTLE_S):
                raise GripperTimeout(f"no reply within {timeout:g} s", device=device, command=name)
        if w.error is not None:
            raise w.error
        assert w.message is not None
        return w.message

    def abandon(self, thread_ident: int) -> None:
        """Give up the request thread ``thread_ident`` waits for, and its later ones until :meth:`resume`:
        each ends at once with GripperTimeout and frees its key (module docstring). Does not wait."""
        with self._lock:
            self._abandoned.add(thread_ident)
            mine = [
                w
                for w in (*self._waiters.values(), *(w for q in self._queued.values() for w in q))
                if w.owner == thread_ident
            ]
        for w in mine:
            w.settle(None, _given_up(w.device, w.name))

    def resume(self, thread_ident: int) -> None:
        """Thread ``thread_ident``'s next request is a new call: no longer given up."""
        with self._lock:
            self._abandoned.discard(thread_ident)

    # ------------------------------------------------------------------------------------------ API

    def node(self, n: int, *, current_limit_ma: int = 1000, timeout: float = 0.5) -> StepfocNode:
        """A handle for node ``n`` (0..15). ``current_limit_ma``: the profile's limit; larger requests are
        clamped to it before sending (docs/protocols.md §2: the firmware itself does not clamp)."""
        return StepfocNode(self, n, current_limit_ma=current_limit_ma, timeout=timeout)

    def subscribe(self, callback: Callable[[can.Message], None]) -> Callable[[], None]:
        """Call ``callback`` (from the reader thread) with every frame received; returns an unsubscribe."""
        self._listeners.append(callback)
        return lambda: self._listeners.remove(callback) if callback in self._listeners else None

    def error_bit(self, node: int) -> bool:
        return self._facts(node).error_bit

    def last_status(self, node: int) -> GripperStatus | None:
        return self._facts(node).status

    def last_heartbeat(self, node: int) -> float | None:
        """``time.monotonic()`` of the last heartbeat received from ``node``."""
        return self._facts(node).heartbeat

    def heartbeat_condition(self, node: int) -> threading.Condition:
        """Notified (by the reader) at every heartbeat of ``node``."""
        cond = self._heartbeats.get(node)
        if cond is None:
            with self._lock:
                cond = self._heartbeats.setdefault(node, threading.Condition())
        return cond

    @property
    def alive(self) -> bool:
        return not self._closed and self._error is None

    def close(self) -> None:
        """Stop the reader; shut the bus down only if this object opened it. Idempotent."""
        if self._closed:
            return
        with self._reopen_lock:  # a reconnection in progress finishes first, so its bus is the one shut down
            self._closed = True
            self._reader.stop()
            self._fail(ConnectionLost("the bus was closed", device=self.device))
            if self._own_bus:
                self.bus.shutdown()


_T = TypeVar("_T")
_T_co = TypeVar("_T_co", covariant=True)


class _Reading(Protocol[_T_co]):
    def __call__(self, timeout: float | None = None) -> _T_co: ...


class _RemoteRead(Generic[_T]):
    """A read that is one remote frame and its answer, decoded by the command table: each read of
    :class:`StepfocNode` is one line naming its command instead of one more copy of the same method body."""

    def __init__(self, command: Cmd, doc: str) -> None:
        self.command = command
        self.__doc__ = doc

    def __set_name__(self, owner: type, name: str) -> None:
        self.name = name

    @overload
    def __get__(self, node: None, owner: type) -> _RemoteRead[_T]: ...
    @overload
    def __get__(self, node: StepfocNode, owner: type) -> _Reading[_T]: ...
    def __get__(self, node: StepfocNode | None, owner: type) -> _RemoteRead[_T] | _Reading[_T]:
        if node is None:
            return self
        command = self.command

        def read(timeout: float | None = None) -> _T:
            return node._remote(command, timeout)

        read.__name__ = read.__qualname__ = self.name
        read.__doc__ = self.__doc__
        return read


StatusCallback = Callable[["GripperStatus | None", "str | None", "GripperError | None"], None]


class StatusRead:
    """:meth:`StepfocNode.start_status`: a poll and, when its status asks for it, frame 26 (the cause of
    the error), both as started requests (:meth:`StepfocBus.start_request`); the second starts from the
    reader thread when the first is answered. The same steps as ``poll()`` then ``fault()``, the same rules
    (:func:`_status_fault`, :func:`_named_fault`: frame 26 not answered in time means no cause) and the same
    timeouts, kept by the bus's reader."""

    def __init__(self, node: StepfocNode, done: StatusCallback) -> None:
        self._node = node
        self._done = done
        self._lock = threading.Lock()  # orders cancel() against the start of the second request
        self._current: PendingRequest | None = None
        self._cancelled = False
        self._status: GripperStatus | None = None
        self._names: list[str] = []
        self.timeout = node.timeout  # of each request (kept by the bus's reader)

    def start(self) -> None:
        node = self._node
        frame = CanFrame(pack_id(node.node, Cmd.GRIPPER_COMMAND), b"", False)
        with self._lock:  # a reply arriving at once waits here, so _current ends as the newest request
            req = node.bus.start_request(
                node.node,
                Cmd.GRIPPER_COMMAND,
                frame,
                self.timeout,
                device=node.device,
                name="poll",
                reply=self._polled,
            )
            if self._current is None:
                self._current = req

    def _polled(self, msg: Message | None, error: GripperError | None) -> None:
        if msg is None:
            self._done(None, None, error)
            return
        st: GripperStatus = msg.value
        cause, names = _status_fault(st)
        if names is None:
            self._done(st, cause, None)
            return
        node = self._node
        with self._lock:
            if self._cancelled:
                return
            self._status, self._names = st, names
            self._current = node.bus.start_request(
                node.node,
                Cmd.ERROR_STATE,
                CanFrame(pack_id(node.node, Cmd.ERROR_STATE), b"", True),
                self.timeout,
                device=node.device,
                name=COMMANDS[Cmd.ERROR_STATE].name,
                reply=self._error_state,
            )

    def _error_state(self, msg: Message | None, error: GripperError | None) -> None:
        if error is not None and not isinstance(error, GripperTimeout):
            self._done(None, None, error)  # as fault() lets every error but a timeout through
            return
        assert self._status is not None
        self._done(self._status, _named_fault(self._names, None if msg is None else msg.value), None)

    def cancel(self) -> None:
        """Give the read up: the request in flight is cancelled (its key free at once); nothing is called.
        Idempotent; never blocks on the device."""
        with self._lock:
            self._cancelled = True
            req = self._current
        if req is not None:
            req.cancel()


class StepfocNode(NodeSetup, Closing):
    """One MSG gripper (node 0..15) on a :class:`StepfocBus`. Values are the device's: bytes 0..255 and mA.
    Its identity, watchdog and heartbeat settings are :class:`~.node_setup.NodeSetup`'s."""

    bus: StepfocBus  # NodeSetup needs only its Heartbeats side

    def __init__(
        self,
        bus: StepfocBus,
        node: int,
        *,
        current_limit_ma: int = 1000,
        timeout: float = 0.5,
        owns_bus: bool = False,
    ) -> None:
        if not isinstance(node, int) or not 0 <= node <= MAX_NODE:
            raise LimitError(f"node {node!r} outside 0..{MAX_NODE}", device=bus.device)
        if current_limit_ma <= 0:
            raise LimitError(f"current limit {current_limit_ma} mA must be positive", device=bus.device)
        self.bus = bus
        self._node = node
        self.current_limit_ma = int(current_limit_ma)
        self.timeout = timeout
        self.last_command: GripperCommand | None = None  # the last 5-byte 61 this handle sent
        self._commanded_at = 0.0  # time.monotonic() of the last 5-byte 61 (see LATCH_GUARD_S)
        self._owns_bus = owns_bus

    # ------------------------------------------------------------------------------------------ basics

    @property
    def node(self) -> int:
        return self._node

    @property
    def device(self) -> str:
        return f"{self.bus.device} node {self._node}"

    @property
    def last_error_bit(self) -> bool:
        """The error bit of the last identifier received from this node (set while it has an active error)."""
        return self.bus.error_bit(self._node)

    @property
    def last_status(self) -> GripperStatus | None:
        return self.bus.last_status(self._node)

    def _timeout(self, timeout: float | None) -> float:
        return self.timeout if timeout is None else timeout

    def send(self, command: int, value: Any = None, *, remote: bool = False) -> None:
        """Send one frame built from the command table; waits for nothing (for commands without a reply)."""
        name = COMMANDS[command].name if command in COMMANDS else f"command {command}"
        frame = encode_frame(self._node, command, value, remote=remote)
        self.bus.send_frame(frame, device=self.device, command=name)

    def _remote(self, command: Cmd, timeout: float | None) -> Any:
        name = COMMANDS[command].name
        frame = CanFrame(pack_id(self._node, command), b"", True)
        return self.bus.request(
            self._node, command, frame, self._timeout(timeout), device=self.device, name=name
        ).value

    def _failed(self, message: str, status: str, command: str) -> CommandFailed:
        """The CommandFailed of a refused or ended command, naming this node (``raise self._failed(...)``)."""
        return CommandFailed(message, status_name=status, device=self.device, command=command)

    def _status_request(self, data: bytes, timeout: float | None, name: str) -> GripperStatus:
        frame = CanFrame(pack_id(self._node, Cmd.GRIPPER_COMMAND), data, False)
        msg = self.bus.request(
            self._node, Cmd.GRIPPER_COMMAND, frame, self._timeout(timeout), device=self.device, name=name
        )
        return msg.value

    # ------------------------------------------------------------------------------------------ gripper

    def poll(self, timeout: float | None = None) -> GripperStatus:
        """Empty 61 -> 60: the status, changing nothing (safe during calibration, docs/protocols.md §2).
        Never within :data:`LATCH_GUARD_S` of this handle's last command, where it would cancel the
        command's latch reset."""
        wait = self._commanded_at + LATCH_GUARD_S - time.monotonic()
        if wait > 0:
            time.sleep(wait)
        return self._status_request(b"", timeout, "poll")

    def make_command(
        self,
        position: int,
        speed: int,
        current_ma: int | None = None,
        *,
        activate: bool = True,
        action: bool = True,
        estop: bool = False,
    ) -> GripperCommand:
        """Validate and clamp a 61 command without sending it."""
        position = _byte(position, "position", self.device, "command")
        speed = _byte(speed, "speed", self.device, "command")
        if current_ma is None:
            current = self.current_limit_ma
        else:
            try:
                current = operator.index(current_ma)
            except TypeError:
                raise LimitError(
                    f"current must be an integer in mA, not {current_ma!r}",
                    device=self.device,
                    command="command",
                ) from None
            if current < 0:
                raise LimitError(f"current {current} mA is negative", device=self.device, command="command")
            # docs/protocols.md §2: clamp to the profile's limit
            current = min(current, self.current_limit_ma)
        return GripperCommand(position, speed, current, bool(activate), bool(action), bool(estop))

    def command(
        self,
        position: int,
        speed: int,
        current_ma: int | None = None,
        *,
        activate: bool = True,
        action: bool = True,
        estop: bool = False,
        timeout: float | None = None,
    ) -> GripperStatus:
        """Send a 61 command; returns the immediate 60 reply (its detection value is still the previous one).
        ``current_ma`` defaults to, and is clamped to, ``current_limit_ma``."""
        return self.send_command(
            self.make_command(position, speed, current_ma, activate=activate, action=action, estop=estop),
            timeout=timeout,
        )

    def send_command(self, cmd: GripperCommand, *, timeout: float | None = None) -> GripperStatus:
        """Send an already built 61 command (no clamping here beyond the byte layout).

        A motion command (action set) is never sent byte-identical to the previous 61 of this handle: the
        firmware treats such a frame as "same command" and keeps its at-position latch, so after a
        calibration, a clear error or a stop from elsewhere the node would report detection 3 at once while
        the jaws still travel (docs/protocols.md §2, "Firmware behaviour a client must survive"). The current
        limit is moved by 1 mA instead, which changes nothing a user can measure.

        The latch is the NODE's: it compares with the last 61 it received from anyone (a previous session,
        another program). A handle that has sent nothing yet cannot know that frame, so its first motion goes
        out twice, first with the current moved by 1 mA: the second frame then differs from the one before
        it, whatever the node had (issue 19: the second run of a script returned at once)."""
        last = self.last_command
        if cmd.action and last is None:
            step = -1 if cmd.current_ma > 0 else 1
            primer = GripperCommand(
                cmd.position, cmd.speed, cmd.current_ma + step, cmd.activate, True, cmd.estop, cmd.release
            )
            self.last_command = primer
            self._status_request(encode_command(primer), timeout, "command")
            last = primer
        if cmd.action and last is not None and encode_command(cmd) == encode_command(last):
            step = -1 if cmd.current_ma > 0 else 1
            cmd = GripperCommand(
                cmd.position, cmd.speed, cmd.current_ma + step, cmd.activate, True, cmd.estop, cmd.release
            )
        data = encode_command(cmd)
        self.last_command = cmd
        try:
            return self._status_request(data, timeout, "command")
        finally:
            self._commanded_at = time.monotonic()

    def fault(self, st: GripperStatus, timeout: float | None = None) -> str | None:
        """Why the node reports an error, or None. The 60 frame names the gripper's estop, watchdog and
        temperature errors; an e-stop by command 0 (another host, a bus tool) only sets the identifier's error
        bit, so frame 26 is asked for the driver's cause (docs/protocols.md §2). Names: ``estop`` for either
        e-stop, ``watchdog``, ``temperature``, ``encoder``, ``vbus``, ``driver``, ``velocity``, ``current``;
        ``error`` when the driver names no cause."""
        cause, names = _status_fault(st)
        if names is None:
            return cause
        try:
            es = self.error_state(timeout)
        except GripperTimeout:
            es = None
        return _named_fault(names, es)

    def start_status(self, done: StatusCallback) -> StatusRead | None:
        """:meth:`poll`, then :meth:`fault`, without blocking: ``done(status, fault, None)`` or
        ``done(None, None, error)`` from the reader thread; ``cancel()`` on the result gives it up. None
        while a poll would have to wait out :data:`LATCH_GUARD_S` (the caller then polls by blocking)."""
        if self._commanded_at + LATCH_GUARD_S > time.monotonic():
            return None
        read = StatusRead(self, done)
        read.start()
        return read

    def wait_motion(
        self, *, timeout: float = 10.0, poll_interval: float = 0.01, stall_s: float = STALL_MIN_S
    ) -> GripperStatus:
        """Poll until the last motion command (:attr:`last_command`) has ended, by the trackers' one rule
        (:func:`.can_waits.wait_motion`). Call after :meth:`command`: the poll that follows reflects it."""
        return can_waits.wait_motion(self, timeout=timeout, poll_interval=poll_interval, stall_s=stall_s)

    def move(
        self,
        position: int,
        speed: int,
        current_ma: int | None = None,
        *,
        wait: bool = True,
        timeout: float = 10.0,
        poll_interval: float = 0.01,
    ) -> GripperStatus:
        """Go to ``position`` (0 open .. 255 closed); with ``wait`` return the status once the motion has
        ended at its target or on an object (:meth:`wait_motion`)."""
        st = self.command(position, speed, current_ma)
        if not st.calibrated:
            raise self._failed(
                "the gripper is not calibrated (calibrate after every power-up)", "not calibrated", "move"
            )
        cause = self.fault(st)
        if cause is not None:
            raise self._failed(f"error active: {cause}", cause, "move")
        return self.wait_motion(timeout=timeout, poll_interval=poll_interval) if wait else st

    def calibrate(
        self, *, wait: bool = True, timeout: float = 30.0, poll_interval: float = 0.05
    ) -> GripperStatus | None:
        """Send 62 and (``wait``) poll with empty 61 frames, which do not abort it, until it has ended.

        On a gripper that is already calibrated the calibrated bit stays set throughout, so the end is read
        from the jaws (:class:`~.can_waits.CalibrationWatch`). ``last_command`` is kept: the node keeps the
        last 61's bytes over a calibration, and :meth:`send_command` makes the next motion differ from them.
        ``timeout`` is wall time; calibration takes seconds on the device."""
        tracker = self.start_calibration()
        if not wait:
            return None
        return can_waits.wait_calibration(
            self, tracker.was_calibrated, timeout=timeout, poll_interval=poll_interval
        )

    def start_calibration(
        self, timeout: float | None = None, *, command: str = "calibrate"
    ) -> CalibrationTracker:
        """Send 62 after one poll that says whether this is a first calibration; returns the sans-IO tracker
        that recognises its end from the following polls (for callers that run their own wait loop).

        An active error forces the driver's mode to idle at its next control tick (docs/protocols.md §2), so
        a 62 then does nothing: CommandFailed naming the driver's error (frame 26) instead."""
        before = self.poll(timeout)
        cause = self.fault(before, timeout)
        if cause is not None:
            raise self._failed(
                f"cannot calibrate: driver error active ({cause}); acknowledge it first", cause, command
            )
        self.send(Cmd.GRIPPER_CALIBRATE)
        return CalibrationTracker(before.calibrated, time.monotonic())

    def estop(self) -> None:
        """Command 0: the node stops and reports the estop error until :meth:`clear_error`."""
        self.send(Cmd.ESTOP)

    def clear_error(self, *, resume: bool = False, timeout: float | None = None) -> GripperStatus:
        """Clear errors so that they stay cleared, in the order the firmware needs.

        Command 1 alone is not enough: if the stored 61 had the estop bit the error comes back at the next
        control step (docs/protocols.md §2, command 1). So a 61 goes FIRST: estop 0, the last command's
        position, speed, current and activate bit, action 0; then 1, which clears every error and idles the
        driver (firmware): nothing moves until the next 5-byte 61. ``resume=True`` then re-sends the last
        motion command (made to differ from the one before, see :meth:`send_command`), which is all the
        firmware allows: the motion restarts from where the jaws are. The returned status is a fresh poll;
        CommandFailed if an error is still active."""
        last = self.last_command
        if last is None:
            st = self.poll(timeout)
            cmd = GripperCommand(st.position, 0, 0, activate=False, action=False, estop=False)
        else:
            cmd = GripperCommand(last.position, last.speed, last.current_ma, last.activate, False, False)
        self.send_command(cmd, timeout=timeout)
        self.send(Cmd.CLEAR_ERROR)
        st = self.poll(timeout)
        cause = self.fault(st, timeout)
        if cause is not None:
            raise self._failed(f"error still active after clearing: {cause}", cause, "clear_error")
        if resume and last is not None and last.action:
            self.send_command(
                GripperCommand(
                    last.position, last.speed, last.current_ma, last.activate, True, False, last.release
                ),
                timeout=timeout,
            )
            st = self.poll(timeout)
        return st

    def idle(self) -> None:
        """Command 12: motor idle (no torque)."""
        self.send(Cmd.IDLE)

    # ------------------------------------------------------------------------------------------ driver

    device_info = _RemoteRead[DeviceInfo](
        Cmd.DEVICE_INFO, "Remote frame 25: hardware, batch date, software version, serial."
    )
    temperature = _RemoteRead[int](Cmd.TEMPERATURE, "Driver temperature in °C.")
    bus_voltage = _RemoteRead[int](Cmd.BUS_VOLTAGE, "Supply voltage in mV.")
    error_state = _RemoteRead[ErrorState](Cmd.ERROR_STATE, "Remote frame 26: the error and state flags.")
    iq = _RemoteRead[int](Cmd.IQ, "Measured motor current (Iq) in mA.")
    encoder = _RemoteRead[EncoderData](
        Cmd.ENCODER, "Remote frame 28: encoder position (ticks) and velocity (ticks/s)."
    )

    def abandon(self, thread_ident: int) -> None:
        """Give up the request thread ``thread_ident`` waits for (:meth:`StepfocBus.abandon`)."""
        self.bus.abandon(thread_ident)

    def resume(self, thread_ident: int) -> None:
        self.bus.resume(thread_ident)

    def close(self) -> None:
        """Close the bus if this handle opened it (see :func:`open_node`); otherwise nothing."""
        if self._owns_bus:
            self.bus.close()


def open_node(
    url: str, *, current_limit_ma: int = 1000, timeout: float = 0.5, **bus_kwargs: Any
) -> StepfocNode:
    """Open ``stepfoc+can://INTERFACE/CHANNEL?node=N`` as a node handle that owns (and closes) its bus."""
    bus, node = StepfocBus.from_url(url, **bus_kwargs)
    try:
        return StepfocNode(bus, node, current_limit_ma=current_limit_ma, timeout=timeout, owns_bus=True)
    except GripperError:
        bus.close()
        raise
