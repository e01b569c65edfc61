"""The input side of a WSG connection: one reader at a time, bytes matched under the lock (sans-IO session).

Who reads (leader/follower): at most one thread is inside ``transport.recv`` at a time, the holder of the
reading role (``reading``: the thread id of a caller or of the connection's reader thread). What it
read is parked in ``held_read`` before anything else happens, so whoever handles an interrupt (Ctrl-C) can
still match it and hand the role back (:mod:`.exchanges`).
"""

from __future__ import annotations

import logging
import threading
import time
from collections import deque
from collections.abc import Callable
from dataclasses import dataclass, field
from threading import get_ident
from typing import Any

from ..errors import ConnectionLost, GripperError, GripperTimeout, ProtocolError
from .commands import command_name, decode_reply
from .dissect import wire_tap
from .interrupts import Waiters, hold
from .protocol import BadLength, ChecksumError, Discarded, Packet
from .session import (
    AutoUpdate,
    Completed,
    Exchange,
    ExchangeFailed,
    ExchangeState,
    Session,
    StaleReply,
    Unsolicited,
)
from .transports import Transport

__all__ = ["POLL", "SILENT_GAP", "Line", "Submitted"]

log = logging.getLogger(__name__)

POLL = 0.05  # one receive's longest wait: bounds how long close() waits for a reader to notice
# docs/protocols.md §1: a half-received packet is dropped after a silent gap of tens of milliseconds.
SILENT_GAP = 0.05


# A request answered by callback; held in the reader's queues, so it lives here (not in callbacks.py, which
# builds on this module: issue 32, no import circles).
Done = Callable[[Packet | None, GripperError | None], None]


@dataclass(eq=False)
class Submitted:
    """One request whose final reply goes to ``done(packet, None)``, or its error to ``done(None, error)``:
    once, unless it was withdrawn first. Made by the caller, so it is known before a fast reply can come."""

    command: int
    payload: bytes
    done: Done
    timeout: float | None = None  # GripperTimeout this long after the send (kept by the reader thread)
    deadline: float | None = field(default=None, repr=False)
    exchange: Exchange | None = field(default=None, repr=False)  # once its slot was taken
    barrier: Submitted | None = field(default=None, repr=False)  # the LOOP proving a stale reply lost
    over: bool = False  # answered, failed or withdrawn: ``done`` is not called (again)

    def reply(self, packet: Packet) -> None:
        if not self.over:
            self.over = True
            self.done(packet, None)

    def fail(self, error: GripperError) -> None:
        if not self.over:
            self.over = True
            self.done(None, error)


def _never(_timeout: float) -> bool:
    return False


def _always(_timeout: float) -> bool:
    return True


@dataclass(frozen=True)
class LineOptions:
    """How a WSG line behaves, given once by the client and handed down whole (not re-listed by every part).

    ``timeout``: an exchange's bound; ``motion_timeout``: a motion's end; ``verify_checksum``: refuse packets
    with a bad CRC; ``stale_ttl``/``stale_final_ttl``: how long a late reply to a given-up exchange is still
    recognised (and dropped) rather than taken for unsolicited; ``silent_gap``: the pause that ends a packet
    on a serial line."""

    device: str | None = None
    timeout: float = 1.0
    motion_timeout: float = 60.0
    verify_checksum: bool = True
    stale_ttl: float = 2.0
    stale_final_ttl: float = 60.0
    silent_gap: float = SILENT_GAP


class Line:
    """One connection's shared state and its input side: who reads, and what the bytes read mean (lock,
    session, reading role). The parts of the connection (:class:`~.exchanges.Exchanges`,
    :class:`~.callbacks.Callbacks`, :class:`~.motion_exchanges.MotionSteps`, the reader thread of
    :class:`~.connection.WsgConnection`) each hold this one object: they share its lock and its state, not
    a base class."""

    def __init__(self, transport: Transport, options: LineOptions) -> None:
        device, timeout, motion_timeout = options.device, options.timeout, options.motion_timeout
        self.device = device or f"wsg {transport.name}"
        self.transport = transport  # as opened (the client shows it); reads and writes go through the tap
        self.wire = wire_tap(transport, self.device)  # DEBUG on grippers.wire: every packet, decoded
        self.stats: dict[str, int] = dict.fromkeys(
            (
                "checksum_errors",
                "bad_lengths",
                "discarded_bytes",
                "stale_replies",
                "unsolicited",
                "updates",
                "lost_replies",
                "barriers",
            ),
            0,
        )
        self.session = Session(
            verify_checksum=options.verify_checksum,
            stale_ttl=options.stale_ttl,
            stale_final_ttl=options.stale_final_ttl,
        )
        self.silent_gap = options.silent_gap
        # docs/protocols.md §1: only a serial line ends a packet by a pause. A TCP stream may pause 40 ms
        # inside a reply (delayed ACK) and CAN frames may be spaced: there the size field and the parser's
        # per-id bound end a packet, never a gap.
        self.gap_rule = bool(getattr(transport, "silent_gap", False))
        self.drain = getattr(transport, "recv_nowait", None)
        # Whether anything may have arrived: a poll() bound method where the transport has one, so the drain
        # before each request costs one call into C when nothing did, which is nearly always
        # (docs/performance.md, target 2); without recv_nowait there is nothing to drain with.
        ready = getattr(transport, "ready", None)
        if self.drain is None:
            ready = _never
        self.ready: Callable[[int], Any] = ready if ready is not None else _always
        self.lock = threading.RLock()
        self.cond = Waiters(self.lock)  # callers wait here for their replies or their slot
        # The background reader waits apart (same lock), so the notifications that wake callers on every reply
        # do not also wake it: a thread wake-up per exchange is what the leader/follower reading avoids.
        self.bg = Waiters(self.lock)
        self.subs: dict[int, list[Any]] = {}  # command -> Subscription (the connection manages them)
        self.lost: ConnectionLost | None = None
        self.closing = False
        self.closed = False
        self.quit = threading.Event()
        # One thread at a time is inside transport.recv: 0 for nobody, else the holder's thread id.
        self.reading = 0
        # (reader, bytes, failure) a role holder read but has not matched yet: matched by whoever handles it.
        self.held_read: tuple[int, bytes | None, BaseException | None] | None = None
        # The exchange of each caller thread between begin() and the end of its wait() (callers read for
        # themselves): keyed by thread, so an interrupted step that adds or removes twice cannot skew a count,
        # and a handler finds the exchange even when Ctrl-C landed before the caller saw it returned.
        self.callers: dict[int, Exchange] = {}
        self.last_rx = time.monotonic()
        # Calls for the reader thread to make outside the lock: subscription values a caller happened to read,
        # replies of callback exchanges (:mod:`.callbacks`), as (function, argument).
        self.deferred: list[tuple[Callable[[Any], None], Any]] = []
        # Callback exchanges (:mod:`.callbacks`): the sent ones by their exchange, and those waiting for their
        # command's slot, per command in order of submission. Kept here: matching completes them.
        self.notify: dict[Exchange, Submitted] = {}
        self.queued: dict[int, deque[Submitted]] = {}
        self.reader_ident: int | None = None
        self.timeout = timeout
        self.motion_timeout = motion_timeout
        self.firmware: Any = None  # FirmwareVersion once 50h was read: decides what is refused locally
        self.stops_sent = 0  # the fence of queued motion requests (exchanges.py, "Stops first")
        # Threads whose caller gave up (exchanges.py, "Abandoned callers"); read without the lock on the
        # hot path: an empty set costs one truth test per step.
        self.abandoned: set[int] = set()
        # Whether replies keep their order on this line: then an abandoned reply needs no reorder margin. A
        # transport that does not say (a plugin's) keeps the margin.
        self.ordered = bool(getattr(transport, "ordered", False))
        # Running subscriptions' (period_ms, changes_only) per command: a plain query repeats them.
        self.sub_params: dict[int, tuple[int, bool]] = {}

    # ----------------------------------------------------------------------------------- matching input

    def background_needed(self) -> bool:
        """Whether bytes may arrive that no waiting caller will read (lock held)."""
        if self.subs or self.deferred or self.session.parser.buffered:
            return True
        # (a caller interrupted right after its request went out may be left in the set: a finished
        # exchange there waits for nobody)
        if any(not exchange.finished for exchange in self.callers.values()):
            return False
        return self.session.expecting(time.monotonic())

    def process(self, data: bytes) -> list[tuple[Any, Any]]:
        """Match received bytes and hand the reading role back (lock held); returns subscription values."""
        self.reading = 0
        now = time.monotonic()
        try:
            session = self.session
            if data:
                self.last_rx = now
                events = session.receive(data, now)
            elif self.gap_rule and session.parser.buffered and now - self.last_rx >= self.silent_gap:
                events = session.reset_parser(now)
            else:
                events = []
            return self.dispatch(events) if events else []
        except Exception:  # noqa: BLE001 - garbage on the line never kills the reading
            log.exception("%s: reader ignored an unexpected error", self.device)
            return []
        finally:
            self.cond.notify_all()  # replies may have arrived, and the reading role is free

    def dispatch(self, events: list[Any]) -> list[tuple[Any, Any]]:
        deliveries: list[tuple[Any, Any]] = []
        stats = self.stats
        notify = self.notify
        for ev in events:
            if type(ev) is Completed:  # the common case: the waiter picks its reply from the exchange
                if notify and (sub := notify.pop(ev.exchange, None)) is not None:
                    deliveries.append((sub.reply, ev.packet))  # nobody waits: the reader calls it back
                continue
            if isinstance(ev, ExchangeFailed):
                if notify and (sub := notify.pop(ev.exchange, None)) is not None:
                    deliveries.append((sub.fail, self.failure(ev.exchange)))
                continue
            if isinstance(ev, AutoUpdate):
                stats["updates"] += 1
                subs = self.subs.get(ev.packet.command)
                if not subs:
                    continue
                try:
                    reply = decode_reply(ev.packet.command, ev.packet.payload)
                except ProtocolError:
                    log.debug("%s: undecodable update %r", self.device, ev.packet)
                    continue
                if reply.ok:
                    deliveries.extend((sub._deliver, reply.value) for sub in subs)
            elif isinstance(ev, StaleReply):
                stats["stale_replies"] += 1
                log.debug("%s: late reply swallowed: %r", self.device, ev.packet)
            elif isinstance(ev, Unsolicited):
                stats["unsolicited"] += 1
                log.debug("%s: unsolicited packet: %r", self.device, ev.packet)
            elif isinstance(ev, ChecksumError):
                stats["checksum_errors"] += 1
            elif isinstance(ev, BadLength):
                stats["bad_lengths"] += 1
            elif isinstance(ev, Discarded):
                stats["discarded_bytes"] += len(ev.raw)
        return deliveries

    def failure(self, exchange: Exchange) -> GripperError:
        """The error a failed or abandoned exchange ends with, naming the device and the command."""
        name = command_name(exchange.command)
        if exchange.state is ExchangeState.ABANDONED:
            return GripperTimeout("abandoned after a timeout", device=self.device, command=name)
        err = exchange.error
        cls = type(err) if isinstance(err, ConnectionLost | ProtocolError) else GripperError
        return cls(err.message if err else "failed", device=self.device, command=name)

    def orphans(self, error: ConnectionLost) -> list[tuple[Callable[[Any], None], Any]]:
        """The line is gone (lock held): every callback exchange, sent or waiting for its slot, fails with
        ``error`` naming its command. The calls are made by the caller once the lock is released."""
        subs = [*self.notify.values(), *(sub for queue in self.queued.values() for sub in queue)]
        self.notify.clear()
        self.queued.clear()
        return [
            (sub.fail, ConnectionLost(error.message, device=self.device, command=command_name(sub.command)))
            for sub in subs
        ]

    def absorb(self, data: bytes | None) -> None:
        """Match bytes a caller read (lock held); updates among them go to the reader thread's callbacks."""
        if data is not None and (found := self.process(data)):
            self.deferred.extend(found)
            self.bg.notify()

    def read_line(self, wait: float) -> BaseException | None:
        """One ``transport.recv`` by the reading role's holder, called with the lock held once: the lock is
        released for the read and held again on return, whatever interrupts land; what was read waits in
        ``held_read`` (matched by :meth:`settle_read`). Returns the interrupt that landed, if any."""
        lock = self.lock
        me = self.reading
        interrupt: BaseException | None = None
        try:
            lock.release()
            self.held_read = (me, self.wire.recv(wait), None)  # one line: no interrupt in between
        except Exception as exc:  # noqa: BLE001 - the line failed: settle_read reports it
            self.held_read = (me, None, exc)
        except BaseException as exc:  # noqa: BLE001 - KeyboardInterrupt: the caller re-raises it
            interrupt = exc
        try:
            late = hold(lock)
        except BaseException as exc:  # noqa: BLE001 - landed on the way into hold(): take it again
            late = hold(lock) or exc
        return interrupt or late

    def settle_read(self) -> None:
        """Match what this thread read (``held_read``) and hand its reading role back (lock held)."""
        mine = get_ident()
        held = self.held_read
        if held is not None and held[0] == mine:
            self.held_read = None
            _, data, lost = held
            if lost is not None:
                self.reading = 0
                self.cond.notify_all()
                self.line_failed(lost)
            elif data is not None:
                self.absorb(data)  # process() hands the role back
                return
        if self.reading == mine:
            self.reading = 0
            self.cond.notify_all()

    def line_failed(self, exc: BaseException) -> None:
        """The transport failed under a reader: every waiter fails with ConnectionLost (unless closing)."""
        if self.quit.is_set():
            return
        lost = (
            exc
            if isinstance(exc, ConnectionLost)
            else ConnectionLost(f"reader failed: {exc!r}", device=self.device)
        )
        self.connection_lost(lost)

    def connection_lost(self, error: ConnectionLost) -> None:
        with self.lock:
            if self.lost is None:
                self.lost = error
            self.session.fail_all(error)
            orphans = self.orphans(error)
            subs = [s for lst in self.subs.values() for s in lst]
            self.cond.notify_all()
        for sub in subs:
            sub._end(error)
        for fail, exc in orphans:
            fail(exc)

    def drain_line(self) -> None:
        """Match what already arrived before a new request is registered (lock held, nobody reading).

        Why: a packet nobody waits for (a duplicated reply, a reply whose marker a proof removed) must be
        consumed and counted now; read after the new request went out it would look like that request's
        reply. One non-blocking read: the line is idle, so it nearly always returns nothing.
        """
        drain = self.drain
        if drain is None:
            return
        try:
            data = drain()
        except ConnectionLost:
            return  # the next read reports it to everybody
        if data:
            self.absorb(data)
