"""The exchange engine of a WSG connection: send a request, read or wait for its reply, survive Ctrl-C.

The matching rules live in :mod:`grippers.drivers.wsg.session` (sans-IO); this module adds the reading, the
waiting with timeouts and the recovery from interrupts. Any number of threads may run exchanges at once:
requests with different command ids run concurrently (state queries while a motion is pending), requests with
the same id take turns (see the session's docstring for why).

Who reads (leader/follower): at most one thread is inside ``transport.recv`` at a time. A caller waiting for
its reply reads the line itself when nobody else does, so a plain request costs no thread hand-over (the
round-trip benchmark, docs/performance.md); other waiters are woken when their reply goes by. The connection's
background thread (:mod:`.connection`) reads only when nobody waits but bytes may still come, among them the
replies of exchanges nobody waits for (:mod:`.callbacks`: the same session, slots and stale markers).

Ctrl-C (issue 13 item 1, issue 23 §3): a KeyboardInterrupt can arrive at any line of an exchange, also inside
the wait for the lock or for a reply. Every step therefore leaves a trace the handler can finish from: the
reading role records its owner, bytes read wait in ``held_read`` until matched, the callers are a set (adding
or removing twice changes nothing) and the waits come back with the lock held (:mod:`.interrupts`). The
handler (:meth:`Exchanges.rescue`) matches what was read, hands the role back and abandons the exchange
as a timeout does (its late reply is swallowed, its id freed). A STOP can then go out at once.

Abandoned callers (issue 23 §3): :meth:`Exchanges.abandon` gives up the call a given thread runs
(the asyncio face does it when the task awaiting a query is cancelled). Its current wait ends at once and
so does every later one of that thread until :meth:`Exchanges.resume`, each as a timeout would: the
exchange is abandoned, its late reply swallowed. Where the line keeps replies in order (TCP, serial, CAN) the
marker needs no reorder margin, so the next request of that id sends the LOOP barrier at once and goes out
as soon as the device answers it; on UDP the margin (``stale_ttl``) stays, as after a timeout.

Stops first (issue 23 §1): STOP and FAST STOP never wait for a stale marker of their id (the session), and
each one fences the motion requests still waiting for their slot: those end with E_CMD_ABORTED instead of
going out after the stop (a servo target queued behind a running move would otherwise start a new motion the
moment the stop ended the old one).

A motion command's steps (its first reply now, its end later) are built from these in
:mod:`.motion_exchanges`.
"""

from __future__ import annotations

import logging
import time
from threading import get_ident
from typing import Any, NoReturn

from ..errors import (
    CommandFailed,
    ConnectionLost,
    GripperError,
    GripperTimeout,
    LimitError,
    NotSupported,
    ProtocolError,
)
from .commands import Cmd, Reply, available, command_name, decode_reply, encode_request
from .interrupts import hold
from .protocol import Packet, Status
from .reading import POLL, SILENT_GAP, Line
from .session import Exchange, ExchangeState

__all__ = ["MOTIONS", "POLL", "SILENT_GAP", "STOPS", "Exchanges"]

log = logging.getLogger(__name__)


# The commands a STOP (22h, WSG manual 4.0.x §3.2.3) ends: a request of these still waiting for its slot
# when a stop is sent is aborted instead of sent.
MOTIONS = frozenset({int(Cmd.HOMING), int(Cmd.PREPOSITION), int(Cmd.GRIP), int(Cmd.RELEASE)})
STOPS = frozenset({int(Cmd.STOP), int(Cmd.FAST_STOP)})


class Exchanges:
    """Requests and replies over one :class:`~.reading.Line` (see the module docstring): the blocking side
    of a connection. The connection (:class:`~.connection.WsgConnection`) holds one, beside the callback
    side and the reader thread; the commands sit on top (:class:`~.client.WsgClient`)."""

    def __init__(self, line: Line) -> None:
        self._line = line

    # ------------------------------------------------------------------------------------------ requests

    def abandon(self, thread_ident: int) -> None:
        """Give up the call that thread ``thread_ident`` runs: its waits end now with GripperTimeout, as
        timeouts would (exchange abandoned, late reply swallowed), until :meth:`resume`. For a caller that
        stops waiting from another thread (an asyncio task cancelled); it does not wait for that thread."""
        with self._line.lock:
            self._line.abandoned.add(thread_ident)
            self._line.cond.notify_all()

    def resume(self, thread_ident: int) -> None:
        """Thread ``thread_ident``'s next call is a new one: its waits are no longer given up."""
        with self._line.lock:
            self._line.abandoned.discard(thread_ident)

    def _given_up(self, cmd: int) -> GripperTimeout:
        return GripperTimeout(
            "abandoned: the caller stopped waiting", device=self._line.device, command=command_name(cmd)
        )

    def usable(self, name: str, internal: bool) -> None:
        if self._line.lost is not None:
            raise ConnectionLost(self._line.lost.message, device=self._line.device, command=name)
        if self._line.closed or (self._line.closing and not internal):
            raise ConnectionLost("client is closed", device=self._line.device, command=name)

    def check_supported(self, cmd: int) -> None:
        if not available(cmd, self._line.firmware):
            raise NotSupported(
                f"not available in firmware {self._line.firmware} (2.x has no 46h and no finger commands)",
                device=self._line.device,
                command=command_name(cmd),
            )

    def encode(self, cmd: int, **fields: Any) -> bytes:
        try:
            return encode_request(cmd, **fields)
        except (LimitError, ProtocolError) as exc:
            raise type(exc)(exc.message, device=self._line.device, command=command_name(cmd)) from None

    def begin(self, cmd: int, payload: bytes, deadline: float, *, internal: bool = False) -> Exchange:
        """Register and send a request; the caller is among ``callers`` until its :meth:`wait` ends.

        When nobody else reads and no subscription needs the reader thread, the caller also takes the reading
        role here (``reading`` is its id): in the same critical section as the send, that saves the lock
        round trip before the read, a good part of a round trip's cost (docs/performance.md).
        """
        me = get_ident()
        if me == self._line.reader_ident:
            raise GripperError(
                "commands cannot be issued from a subscription callback (reader thread)",
                device=self._line.device,
                command=command_name(cmd),
            )
        session = self._line.session
        exchange: Exchange | None = None
        fence = self._line.stops_sent
        try:
            with self._line.lock:
                if cmd in STOPS:
                    self._line.stops_sent += 1  # before the slot: motion requests queued from now on give way
                    self._line.cond.notify_all()
                while True:
                    if self._line.lost is not None or self._line.closing or self._line.closed:
                        self.usable(command_name(cmd), internal)
                    if self._line.abandoned and me in self._line.abandoned:
                        raise self._given_up(cmd)
                    if fence != self._line.stops_sent and cmd in MOTIONS:
                        raise CommandFailed(
                            "aborted by a stop sent while it waited for its turn (not sent)",
                            status=int(Status.E_CMD_ABORTED),
                            status_name="E_CMD_ABORTED",
                            device=self._line.device,
                            command=command_name(cmd),
                        )
                    if not self._line.reading and not self._line.subs and self._line.ready(0):
                        self._line.drain_line()
                    now = time.monotonic()
                    before = session.seq
                    try:
                        opened = session.open(cmd, payload, now)
                    except BaseException:  # Ctrl-C right after open(): its result is lost, not the slot
                        session.withdraw(cmd, before)
                        raise
                    if opened is not None:
                        exchange, raw = opened
                        self._line.callers[me] = exchange  # removed by the wait() that follows
                        if not (self._line.reading or self._line.subs or self._line.closing):
                            self._line.reading = me  # the role's owner: a rescue after Ctrl-C hands it back
                        break
                    self._wait_for_slot(cmd, now, deadline, internal)
            self._line.wire.send(raw)
        except BaseException as exc:
            if exchange is None:
                raise
            with self._line.lock:
                self._line.callers.pop(me, None)
                if self._line.reading == me:  # never leave the reading role taken by a caller that is gone
                    self._line.reading = 0
                    self._line.cond.notify_all()
                if not isinstance(exc, ConnectionLost):
                    # Interrupted (KeyboardInterrupt) or refused: whether the bytes left is unknown, so the
                    # slot is held like a timed-out request's, long enough to swallow a late reply.
                    session.abandon(exchange, time.monotonic())
            if not isinstance(exc, ConnectionLost):
                raise
            self._line.connection_lost(exc)  # fails the exchange and wakes everybody
            raise ConnectionLost(exc.message, device=self._line.device, command=command_name(cmd)) from None
        return exchange

    def _sleep(self, timeout: float) -> None:
        """Wait on ``cond`` (lock held once); an interrupt is raised with the lock held again."""
        interrupt = self._line.cond.wait(timeout)
        if interrupt is not None:
            raise interrupt

    def _wait_for_slot(self, cmd: int, now: float, deadline: float, internal: bool) -> None:
        """The slot of ``cmd`` is held (lock held): wait a little, or run the barrier that proves a stale
        reply lost (with the lock released); GripperTimeout at the deadline."""
        if deadline - now <= 0:
            raise GripperTimeout(
                "a previous exchange of this command is still outstanding (one per command id)",
                device=self._line.device,
                command=command_name(cmd),
            )
        session = self._line.session
        if not session.needs_barrier(cmd, now):
            self._sleep(min(deadline - now, POLL))
            return
        lock = self._line.lock
        error: BaseException | None = None
        try:
            lock.release()  # begin() holds it once (its own ``with``)
            self._barrier(cmd, deadline, internal)
        except BaseException as exc:  # noqa: BLE001 - raised below, once the lock is held again
            error = exc
        try:
            late = hold(lock)
        except BaseException as exc:  # noqa: BLE001 - landed on the way into hold(): take it again
            late = hold(lock) or exc
        session.is_busy(cmd, time.monotonic())  # drops the marker the barrier proved lost
        self._line.stats["lost_replies"] = session.lost_replies
        if error is not None:
            raise error
        if late is not None:
            raise late

    def _barrier(self, cmd: int, deadline: float, internal: bool) -> None:
        """Prove a stale reply of ``cmd`` lost: a LOOP with a fresh nonce, answered after anything sent
        before it (the device answers in order). GripperTimeout when even that gets no reply."""
        self._line.stats["barriers"] += 1
        nonce = self._line.session.barrier_payload()
        wait = max(deadline - time.monotonic(), 0.001)
        try:
            packet = self.exchange(Cmd.LOOP, nonce, wait, internal)
        except GripperTimeout:
            raise GripperTimeout(
                "a previous exchange of this command is still outstanding (one per command id) and the "
                "device did not answer the LOOP that would prove its reply lost",
                device=self._line.device,
                command=command_name(cmd),
            ) from None
        if packet.status:
            log.debug("%s: barrier LOOP answered %s", self._line.device, Status.describe(packet.status))

    # ------------------------------------------------------------------------------------------- replies

    def read_own_reply(self, exchange: Exchange, wait: float) -> Packet | None:
        """The first read of a caller that took the reading role in :meth:`begin` (nothing can have arrived
        before): when the bytes are exactly its final reply, which they nearly always are on TCP and UDP, the
        exchange is done here without the general matching. Otherwise they are matched as usual and None sends
        the caller on to :meth:`wait`, still among the callers.
        """
        with self._line.lock:
            interrupt = self._line.read_line(wait if wait < POLL else POLL)
            held = self._line.held_read
            if interrupt is None and held is not None and held[1]:
                packet = self._line.session.take_reply(exchange, held[1])
                if packet is not None:
                    self._line.held_read = None
                    self._line.reading = 0  # (no _last_rx: it matters only while the parser holds bytes)
                    self._line.cond.notify_all()  # the reading role is free
                    self._line.callers.pop(get_ident(), None)
                    if self._line.queued:
                        self._line.bg.notify()  # a callback request may wait for this slot (.callbacks)
                    return packet
            self._line.settle_read()
            if interrupt is not None:
                raise interrupt
        return None

    def wait(
        self,
        exchange: Exchange,
        deadline: float,
        *,
        final: bool,
        abandon: bool = True,
        waited: float | None = None,
        keep: bool = False,
    ) -> Packet:
        """Wait for ``exchange``'s reply (``final``: past E_CMD_PENDING), reading the line when nobody else
        does. ``keep``: the caller stays registered with its exchange on success (a motion between its
        E_CMD_PENDING and the wait for its end: an interrupt there is still rescued)."""
        with self._line.lock:
            self._line.callers[get_ident()] = exchange
            leave = False  # an interrupt leaves the caller registered: rescue() abandons its exchange
            try:
                packet = self._await(exchange, deadline, final, abandon, waited)
                leave = not keep
                return packet
            except GripperError:
                leave = True
                raise
            finally:
                if leave:
                    self.leave()

    def _await(
        self, exchange: Exchange, deadline: float, final: bool, abandon: bool, waited: float | None
    ) -> Packet:
        """The wait loop (lock held once)."""
        while True:
            state = exchange.state
            if state is ExchangeState.DONE:
                assert exchange.reply is not None
                return exchange.reply
            if state is ExchangeState.PENDING and not final:
                assert exchange.ack is not None
                return exchange.ack
            if state is ExchangeState.FAILED or state is ExchangeState.ABANDONED:
                self._raise_failed(exchange)
            now = time.monotonic()
            if now >= deadline:
                self._timed_out(exchange, now, abandon, waited)
            if self._line.abandoned and get_ident() in self._line.abandoned:
                if abandon:
                    self._line.session.abandon(exchange, now, margin=0.0 if self._line.ordered else None)
                    self._line.cond.notify_all()
                raise self._given_up(exchange.command)
            if (
                self._line.reading
                or self._line.subs
                or self._line.quit.is_set()
                or self._line.lost is not None
            ):
                if not self._line.reading:
                    self._line.bg.notify()  # subscriptions: the reader thread reads (and runs the callbacks)
                self._sleep(deadline - now)
                continue
            # Nobody is reading and no subscription needs the reader thread: read for ourselves.
            self._line.reading = get_ident()
            interrupt = self._line.read_line(min(deadline - now, POLL))
            self._line.settle_read()
            if interrupt is not None:
                raise interrupt

    def leave(self) -> None:
        """A caller is done with its exchange (lock held)."""
        self._line.callers.pop(get_ident(), None)
        if self._line.queued or (not self._line.callers and self._line.background_needed()):
            # e.g. a pending motion's final reply: nobody waits to read it; or a callback request waits for
            # the slot this exchange held (.callbacks)
            self._line.bg.notify()

    def rescue(self, abandon: bool = True) -> None:
        """Ctrl-C (any BaseException but a GripperError) reached a caller between its steps: whatever step it
        hit, match what it read, give the reading role back and, unless told not to, abandon its exchange as
        a timeout does, so no command id and no reader stays taken (issue 13 item 1)."""
        with self._line.lock:
            self._line.settle_read()
            exchange = self._line.callers.pop(get_ident(), None)
            if exchange is not None and abandon and not exchange.finished:
                self._line.session.abandon(exchange, time.monotonic())
                self._line.cond.notify_all()
                self._line.bg.notify()  # the late reply: the reader thread reads it when nobody else does

    def _raise_failed(self, exchange: Exchange) -> NoReturn:
        raise self._line.failure(exchange)

    def _timed_out(self, exchange: Exchange, now: float, abandon: bool, waited: float | None) -> NoReturn:
        state = exchange.state
        if abandon:
            self._line.session.abandon(exchange, now)
            self._line.cond.notify_all()
        what = "final reply" if state is ExchangeState.PENDING else "reply"
        after = f" within {waited:g} s" if waited is not None else ""
        raise GripperTimeout(
            f"no {what}{after}", device=self._line.device, command=command_name(exchange.command)
        )

    def check(self, cmd: int, packet: Packet) -> Reply:
        try:
            reply = decode_reply(cmd, packet.payload)
        except ProtocolError as exc:
            raise ProtocolError(exc.message, device=self._line.device, command=command_name(cmd)) from None
        if not reply.ok:
            code = int(reply.status)
            raise CommandFailed(
                Status.describe(code),
                status=code,
                status_name=reply.status_name,
                device=self._line.device,
                command=command_name(cmd),
            )
        return reply

    # ---------------------------------------------------------------------------------------- exchanges

    def call(
        self,
        cmd: int,
        *,
        timeout: float | None = None,
        payload: bytes | None = None,
        internal: bool = False,
        **fields: Any,
    ) -> Reply:
        self.check_supported(cmd)
        if payload is None:
            payload = self.encode(cmd, **fields)
        return self.check(
            cmd, self.exchange(cmd, payload, self._line.timeout if timeout is None else timeout, internal)
        )

    def exchange(self, cmd: int, payload: bytes, wait: float, internal: bool = False) -> Packet:
        """Send a request and return its final reply (past E_CMD_PENDING) within ``wait`` seconds."""
        deadline = time.monotonic() + wait
        try:
            exchange = self.begin(cmd, payload, deadline, internal=internal)
            if (
                self._line.reading == get_ident()
                and (packet := self.read_own_reply(exchange, wait)) is not None
            ):
                return packet
            return self.wait(exchange, deadline, final=True, waited=wait)
        except GripperError:
            raise
        except BaseException:
            self.rescue()
            raise

    def request(
        self, cmd: int, payload: bytes = b"", *, timeout: float | None = None, check: bool = False
    ) -> Packet:
        """Send any command with a raw payload; the final reply packet (after E_CMD_PENDING, if any).

        With ``check`` a status other than E_SUCCESS raises CommandFailed; without, the caller reads
        ``packet.status``.
        """
        self.check_supported(cmd)
        packet = self.exchange(cmd, bytes(payload), self._line.timeout if timeout is None else timeout)
        if check:
            self.check(cmd, packet)
        return packet
