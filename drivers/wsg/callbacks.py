"""Exchanges nobody waits for: send a request, and the reply (or the error) goes to a callback (issue 20 §2).

Why: the asyncio face reads the state with no thread blocked on it. A blocking exchange
(:mod:`.exchanges`) parks its caller until the reply comes; here the reply is matched by whoever reads the
line (the connection's reader thread, usually: the session holds the exchange as outstanding, which is what
sends the reader to the line) and handed back by a call, made by the reader thread outside the lock. The
matching, the slots and the stale markers are the session's, exactly as for a blocking exchange, so both
kinds can run at once on one connection; nothing here depends on the transport.

A request whose command's slot is held (another exchange of that id, or a stale marker left by an abandoned
one) waits in a queue, never a thread: the reader thread sends it once the slot is free, and where only a
proof can free it (:meth:`Session.needs_barrier`) it sends the same LOOP barrier a blocking caller would.

A request with a ``timeout`` times out as a blocking one does (GripperTimeout, its exchange abandoned, the
late reply swallowed): the connection's reader thread, which wakes at least every POLL, keeps the time, so
no caller needs a timer of its own. The caller may give a request up sooner with
:meth:`Callbacks.withdraw` (a cancelled task), which abandons the exchange as a cancelled blocking call
is abandoned (where the line keeps replies in order no reorder margin, see ``Exchanges.abandon``). A
lost or closed line fails every such request with ConnectionLost.
"""

from __future__ import annotations

import time
from collections import deque
from threading import get_ident

from ..errors import ConnectionLost, GripperError, GripperTimeout
from .commands import Cmd, command_name
from .protocol import Packet
from .reading import Line, Submitted

__all__ = ["Callbacks", "Submitted"]


def _ignore(_packet: Packet | None, _error: GripperError | None) -> None:
    pass


class Callbacks:
    """Requests answered by callback over a :class:`~.reading.Line` (see the module docstring): the side of
    a connection nobody waits on; its reader thread (:class:`~.connection.WsgConnection`) drives it."""

    def __init__(self, line: Line) -> None:
        self._line = line

    def waiting(self) -> int:
        """How many callback requests are on the wire without their reply, or queued for their slot."""
        with self._line.lock:
            return len(self._line.notify) + sum(len(q) for q in self._line.queued.values())

    def submit(self, sub: Submitted) -> None:
        """Send ``sub``'s request now, or queue it for its command's slot; never blocks on the device.

        From any thread, the reader's included (a callback submitting the next request). A line already lost
        or closed calls ``sub.done`` with ConnectionLost before returning."""
        cmd = sub.command
        with self._line.lock:
            if self._line.lost is not None or self._line.closing or self._line.closed:
                error = self._line.lost or ConnectionLost("client is closed", device=self._line.device)
                sub.over = True
                lost = ConnectionLost(error.message, device=self._line.device, command=command_name(cmd))
            else:
                lost = None
                if not self._line.reading and not self._line.subs and self._line.ready(0):
                    self._line.drain_line()  # what arrived is no reply of this request (as in begin)
                raw = None if cmd in self._line.queued else self._open(sub, time.monotonic())
                if raw is None:
                    self._line.queued.setdefault(cmd, deque()).append(sub)
                    self._line.bg.notify()  # the reader sends it once the slot is free (or the barrier)
        if lost is not None:
            sub.done(None, lost)
        elif raw is not None:
            self.send(sub, raw)
            if self._line.bg.waiting:
                # The reader reads the reply: woken once the request is out, so that on a busy machine the
                # woken thread does not run first and delay the send. (A reader about to sleep saw the
                # exchange opened above, under the lock, and reads without being woken.)
                with self._line.lock:
                    self._line.bg.notify()

    def withdraw(self, sub: Submitted, error: GripperError | None = None) -> None:
        """Give ``sub`` up (idempotent, never blocks): dropped from the queue, or its exchange abandoned as a
        cancelled blocking call's is (late reply swallowed); ``done`` is no longer called, but once with
        ``error`` when one is given (a timeout the reader keeps) and ``sub`` was not over yet."""
        with self._line.lock:
            tell = error is not None and not sub.over
            if error is not None and not tell:
                return  # answered or failed meanwhile: that outcome stands
            sub.over = True
            exchange = sub.exchange
            if exchange is None:
                queue = self._line.queued.get(sub.command)
                if queue is not None and sub in queue:
                    queue.remove(sub)
                    if not queue:
                        del self._line.queued[sub.command]
            elif self._line.notify.pop(exchange, None) is not None and not exchange.finished:
                self._line.session.abandon(
                    exchange, time.monotonic(), margin=0.0 if self._line.ordered else None
                )
                self._line.cond.notify_all()
                self._line.bg.notify()  # the late reply: read by the reader thread when nobody else reads
            barrier, sub.barrier = sub.barrier, None
        if barrier is not None:
            self.withdraw(barrier)
        if tell:
            assert error is not None
            sub.done(None, error)

    def late(self, now: float) -> bool:
        """A sent callback request's deadline has passed (lock held)."""
        return any(sub.deadline is not None and now >= sub.deadline for sub in self._line.notify.values())

    def expire(self, now: float) -> None:
        """Time out the sent callback requests whose deadline passed (the reader thread, lock not held), in
        a blocking exchange's words; the exchange is abandoned as a timed-out one is."""
        with self._line.lock:
            late = [
                sub
                for sub in self._line.notify.values()
                if sub.deadline is not None and now >= sub.deadline and not sub.over
            ]
        for sub in late:  # abandoned (its late reply swallowed), and its caller told once
            text = f"no reply within {sub.timeout:g} s"
            self.withdraw(
                sub, GripperTimeout(text, device=self._line.device, command=command_name(sub.command))
            )

    def _open(self, sub: Submitted, now: float) -> bytes | None:
        """Take ``sub``'s slot and register it (lock held): the bytes to send; None while the slot is held."""
        opened = self._line.session.open(sub.command, sub.payload, now)
        if opened is None:
            return None
        exchange, raw = opened
        sub.exchange = exchange
        if sub.timeout is not None:
            # From the send, not from submit(): a request queued behind others of its command (100 awaits
            # at once) waits its turn as calls queued in the asyncio face did; each one out is bounded, so
            # the queue drains in finite time.
            sub.deadline = now + sub.timeout
        self._line.notify[exchange] = sub
        self._line.stats["lost_replies"] = (
            self._line.session.lost_replies
        )  # open() may have dropped a proved marker
        return raw

    def send(self, sub: Submitted, raw: bytes) -> None:
        """Write an opened request (lock not held, as in ``Exchanges.begin``); a failing line fails it."""
        try:
            self._line.wire.send(raw)
        except ConnectionLost as exc:
            self._line.connection_lost(exc)  # fails this exchange too, with every other
        except GripperError as exc:
            # Whether the bytes left is unknown: the slot is held like a timed-out request's.
            with self._line.lock:
                found = self._line.notify.pop(sub.exchange, None) if sub.exchange is not None else None
                if found is not None and sub.exchange is not None:
                    self._line.session.abandon(sub.exchange, time.monotonic())
            sub.fail(type(exc)(exc.message, device=self._line.device, command=command_name(sub.command)))

    def start_queued(self) -> list[tuple[Submitted, bytes]]:
        """Open every queued request whose slot is free now, or send the barrier that proves a stale reply
        lost (lock held; the reader thread calls it). Returns what to send once the lock is released."""
        session = self._line.session
        out: list[tuple[Submitted, bytes]] = []
        now = time.monotonic()
        for cmd, queue in list(self._line.queued.items()):
            head = queue[0]
            if session.needs_barrier(cmd, now):
                if head.barrier is None or head.barrier.over:
                    self._line.stats["barriers"] += 1
                    head.barrier = Submitted(int(Cmd.LOOP), session.barrier_payload(), _ignore)
                    raw = self._open(head.barrier, now)
                    if raw is None:  # another LOOP is out: the barrier waits its turn
                        self._line.queued.setdefault(int(Cmd.LOOP), deque()).append(head.barrier)
                    else:
                        out.append((head.barrier, raw))
                continue
            raw = self._open(head, now)
            if raw is None:
                continue
            queue.popleft()
            if not queue:
                del self._line.queued[cmd]
            out.append((head, raw))
        return out

    def take_callback_reply(self) -> tuple[Submitted, Packet] | None:
        """After the reader thread's read (lock held): when the bytes are exactly the final reply of the one
        callback exchange out, which they nearly always are, complete it here and return it to be called
        back at once; otherwise match them as usual (:meth:`~.reading.Line.settle_read`) and return None.

        Why: the same shortcut a blocking caller takes for its own reply (``Exchanges.read_own_reply``): the
        general matching and a turn of the reader's loop per reply would cost the callback path what it
        saves."""
        held = self._line.held_read
        notify = self._line.notify
        if held is not None and held[1] and len(notify) == 1 and held[0] == get_ident():
            exchange, sub = next(iter(notify.items()))
            packet = self._line.session.take_reply(exchange, held[1])
            if packet is not None:
                del notify[exchange]
                self._line.held_read = None
                self._line.reading = 0
                self._line.cond.notify_all()  # the reading role is free
                return sub, packet
        self._line.settle_read()
        return None
