"""Request/reply matching for one WSG connection (sans-IO: bytes and time in, events out).

The WSG protocol has no sequence numbers: a reply carries only its command id. Three kinds of packets share
that id space, and this module decides which is which:

* **Immediate replies.** The device answers requests in order, so the first packet of id X after a request
  for X is its reply. To keep that unambiguous the session allows **one exchange per command id** on the
  wire at a time; a second request for X waits (in the client, bounded by its timeout) until the first is
  finished. Requests with different ids run concurrently, which is what lets state queries flow while a
  motion is pending.
* **E_CMD_PENDING, then the final reply** (WSG manual 4.0.x §1.3). A PENDING reply moves the exchange to the
  pending phase; the next packet of that id is its final reply. The slot of that id stays busy until then.
* **Auto updates** (40h, 41h, 43h-45h; docs/protocols.md §1) reuse the id of their command. A packet of a
  subscribed id is an update whenever no request of that id is outstanding; while one is outstanding, the next
  packet of that id is taken as its reply. The two carry the same data (the current value), so the only
  consequence of an update overtaking a reply is that the reply itself is then delivered as an update.
* **Late replies.** A request that timed out (or whose caller was interrupted: Ctrl-C) is *abandoned*, not
  forgotten: a stale marker for its id swallows the next packet of that id (for a pending motion: the final
  reply, which may come much later), so a late reply is never matched to a later request. The slot stays
  busy while the marker lives. A marker is never dropped on a timer alone (a reply 4 s late would then answer
  the next request): it goes when its packet comes, or when the device has *proved* the reply lost. The
  device answers requests in the order it receives them (WSG manual 4.0.x §1.3; docs/protocols.md §1), so
  once the immediate reply of a request sent *after* the abandoned one has arrived, the abandoned one's reply
  is not coming; the marker then goes once ``stale_ttl`` has also passed (the margin for a network that
  reorders datagrams). When no other traffic supplies that proof, :meth:`Session.needs_barrier` tells the
  client to send one: a LOOP with a fresh nonce (see below). Only the marker of a pending motion's final
  reply still expires by time (``stale_final_ttl``): a final reply keeps no order with other replies.
* **LOOP** (06h) echoes its data, so its reply is recognised by content: a LOOP packet whose data is not the
  waiting request's is a late or duplicated echo (swallowed and counted), and a LOOP request never waits for
  a LOOP marker. That makes a LOOP with a unique nonce the barrier that proves other replies lost. STOP and
  FAST STOP never wait for their markers either: a stop must go out at once (see ``_NEVER_HELD``).
* **Duplicates.** A packet of an id nobody waits for is :class:`Unsolicited` (counted by the client, never
  kept for a later request). The client reads what already arrived before it registers a new request, so a
  duplicate that came in between two requests of one id is consumed, not taken as the second one's reply.
* **Size.** A header whose size field exceeds what a reply of its id can hold (the command table's layout;
  for ids with an open-ended reply such as finger data, only while a request of that id is outstanding) is a
  false header at once (:class:`~.protocol.BadLength`), so on a stream without silent gaps (TCP, CAN) a
  false header holds the packets behind it back for at most the largest reply of an expected id.

A reply that fails its checksum fails the exchange waiting on that id at once (with ProtocolError) instead of
letting it run into a timeout, except for subscribed ids, where the corrupt packet may as well have been an
update.
"""

from __future__ import annotations

from dataclasses import dataclass
from enum import Enum

from ..errors import GripperError, ProtocolError
from .commands import COMMANDS, Cmd, CommandSpec, command_name
from .protocol import (
    CRC_AFTER_PREAMBLE,
    HEADER_SIZE,
    MAX_PAYLOAD,
    PREAMBLE,
    TRAILER_SIZE,
    ChecksumError,
    Packet,
    PacketParser,
    ParseEvent,
    Status,
    crc16,
    encode_packet,
    whole_packet,
)

__all__ = [
    "Acknowledged",
    "AutoUpdate",
    "Completed",
    "Exchange",
    "ExchangeFailed",
    "ExchangeState",
    "Session",
    "SessionEvent",
    "StaleReply",
    "Unsolicited",
]


class ExchangeState(Enum):
    SENT = "sent"  # waiting for the immediate reply
    PENDING = "pending"  # E_CMD_PENDING received, waiting for the final reply
    DONE = "done"  # final reply received
    FAILED = "failed"  # corrupted reply or connection lost
    ABANDONED = "abandoned"  # timed out; a stale marker swallows its late reply


@dataclass(eq=False, slots=True)
class Exchange:
    """One request and its replies."""

    command: int
    payload: bytes
    sent_at: float
    seq: int = 0  # order of sending on this connection: what proves an older reply lost
    state: ExchangeState = ExchangeState.SENT
    ack: Packet | None = None
    reply: Packet | None = None
    error: GripperError | None = None

    @property
    def finished(self) -> bool:
        return self.state in (ExchangeState.DONE, ExchangeState.FAILED, ExchangeState.ABANDONED)


@dataclass(frozen=True, slots=True)
class Acknowledged:
    """E_CMD_PENDING for ``exchange``: the command runs, the final reply follows later."""

    exchange: Exchange
    packet: Packet


@dataclass(frozen=True, slots=True)
class Completed:
    """The final reply of ``exchange`` (any status but E_CMD_PENDING)."""

    exchange: Exchange
    packet: Packet


@dataclass(frozen=True, slots=True)
class ExchangeFailed:
    exchange: Exchange
    error: GripperError


@dataclass(frozen=True, slots=True)
class AutoUpdate:
    packet: Packet


@dataclass(frozen=True, slots=True)
class StaleReply:
    """A late reply to an abandoned exchange, swallowed."""

    packet: Packet
    exchange: Exchange


@dataclass(frozen=True, slots=True)
class Unsolicited:
    """A packet nobody waits for: no request, no subscription, no stale marker of its id."""

    packet: Packet


SessionEvent = Acknowledged | Completed | ExchangeFailed | AutoUpdate | StaleReply | Unsolicited | ParseEvent


@dataclass(slots=True)
class _Stale:
    exchange: Exchange
    expects_final: bool
    expires: float  # final-reply markers: the end of their life; others: the earliest they may go
    proved_lost: bool = False  # a later request's immediate reply arrived first: this reply is not coming


class Session:
    """The matching state of one connection; the caller owns the transport, the threads and the clock."""

    def __init__(
        self,
        *,
        verify_checksum: bool = True,
        max_payload: int = MAX_PAYLOAD,
        stale_ttl: float = 2.0,
        stale_final_ttl: float = 60.0,
    ) -> None:
        self.stale_ttl = stale_ttl
        self.stale_final_ttl = stale_final_ttl
        self._active: dict[int, Exchange] = {}
        self._stale: dict[int, _Stale] = {}
        self._subscribed: set[int] = set()
        self.seq = 0  # requests opened so far on this connection (the last one's Exchange.seq)
        #: Markers dropped because a later reply proved theirs lost (the client reports it in its stats).
        self.lost_replies = 0
        self.parser = PacketParser(
            verify_checksum=verify_checksum, max_payload=max_payload, max_size=self._max_size
        )
        # Most requests repeat byte for byte (state queries): their packets are encoded once.
        self._packets: dict[tuple[int, bytes], bytes] = {}

    # ------------------------------------------------------------------------------------------- requests

    def is_busy(self, command: int, now: float) -> bool:
        """Whether a request for ``command`` must wait: an exchange or a stale marker holds its slot."""
        if command in self._active:
            return True
        if not self._stale or command in _NEVER_HELD:
            return False
        stale = self._stale.get(command)
        if stale is None:
            return False
        if stale.expires <= now and (stale.expects_final or stale.proved_lost):
            del self._stale[command]
            if not stale.expects_final:
                self.lost_replies += 1
            return False
        return True

    def needs_barrier(self, command: int, now: float) -> bool:
        """Whether ``command`` waits for a marker that only a proof can remove (its ``stale_ttl`` is over and
        no later reply has come): the client then sends a LOOP nonce (:meth:`barrier_payload`)."""
        stale = self._stale.get(command) if self._stale else None
        return (
            stale is not None
            and command not in _NEVER_HELD
            and not stale.expects_final
            and not stale.proved_lost
            and stale.expires <= now
        )

    def barrier_payload(self) -> bytes:
        """A LOOP payload no earlier LOOP of this connection carried (its reply is recognised by content)."""
        return b"sync" + (self.seq + 1).to_bytes(8, "little")

    def send(self, command: int, payload: bytes = b"", *, now: float) -> tuple[Exchange, bytes]:
        """Register a request and return it with the bytes to write. The slot must be free (see is_busy)."""
        opened = self.open(command, payload, now)
        if opened is None:
            raise GripperError("another exchange of this id is outstanding", command=command_name(command))
        return opened

    def open(self, command: int, payload: bytes, now: float) -> tuple[Exchange, bytes] | None:
        """:meth:`send` when the slot is free, else None: is_busy and send in one step for the client."""
        if command in self._active or (self._stale and self.is_busy(command, now)):
            return None
        self.seq += 1
        payload = bytes(payload)
        key = (command, payload)
        raw = self._packets.get(key)
        if raw is None:
            raw = encode_packet(command, payload)
            if len(payload) <= 8 and len(self._packets) < 256:  # bounded: motions carry varying floats
                self._packets[key] = raw
        exchange = Exchange(command, payload, now, self.seq)
        self._active[command] = exchange
        return exchange, raw

    def withdraw(self, command: int, seq_before: int) -> None:
        """Forget an exchange of ``command`` opened after ``seq_before`` that was never sent (the caller was
        interrupted between :meth:`open` and the send): nothing can answer it, so no marker is left."""
        exchange = self._active.get(command)
        if exchange is not None and exchange.seq > seq_before:
            del self._active[command]
            exchange.state = ExchangeState.FAILED

    def abandon(self, exchange: Exchange, now: float, *, margin: float | None = None) -> None:
        """The caller stopped waiting (timeout): leave a stale marker that swallows the late reply.

        ``margin`` replaces ``stale_ttl`` for an immediate reply's marker: 0 where the line keeps replies in
        order (TCP, serial, CAN) and the caller gave up early (a cancelled asyncio call), so the next request
        of that id can prove the reply lost with a barrier at once instead of waiting out the margin."""
        if self._active.get(exchange.command) is not exchange:
            return
        del self._active[exchange.command]
        pending = exchange.state is ExchangeState.PENDING
        exchange.state = ExchangeState.ABANDONED
        ttl = self.stale_final_ttl if pending else self.stale_ttl if margin is None else margin
        self._stale[exchange.command] = _Stale(exchange, pending, now + ttl)

    def fail_all(self, error: GripperError) -> list[Exchange]:
        """Connection lost or closed: every outstanding exchange fails with ``error``."""
        failed = list(self._active.values())
        for exchange in failed:
            exchange.state = ExchangeState.FAILED
            exchange.error = error
        self._active.clear()
        self._stale.clear()
        return failed

    def outstanding(self) -> list[Exchange]:
        return list(self._active.values())

    def expecting(self, now: float) -> bool:
        """Whether a packet may still arrive for an exchange or a stale marker within its ``stale_ttl``
        (cheap: no lists built). Older markers wait for a proof; what arrives for them meanwhile is read
        before the next request (the client drains the line) or by whoever reads next."""
        if self._active:
            return True
        return bool(self._stale) and any(s.expires > now for s in self._stale.values())

    def stale_ids(self, now: float) -> list[int]:
        """Ids whose slot a stale marker holds at ``now``."""
        return [cmd for cmd in list(self._stale) if self.is_busy(cmd, now)]

    def _max_size(self, command: int) -> int:
        """The parser's size bound for ``command`` (see the module docstring, "Size")."""
        limit = _REPLY_MAX.get(command)
        if limit is not None:
            return limit
        # An open-ended reply (finger data, device tag, an id the table does not know): only while expected.
        if command in self._active or command in self._stale:
            return MAX_PAYLOAD
        return 2

    def _prove(self, exchange: Exchange) -> None:
        """``exchange``'s first reply arrived: every older marker's reply was lost (replies come in order)."""
        seq = exchange.seq
        for stale in self._stale.values():
            if stale.exchange.seq < seq and not stale.expects_final:
                stale.proved_lost = True

    # ---------------------------------------------------------------------------------------- subscriptions

    def subscribe(self, command: int) -> None:
        """Packets of ``command`` that answer no request are auto updates from now on."""
        self._subscribed.add(command)

    def unsubscribe(self, command: int) -> None:
        self._subscribed.discard(command)

    @property
    def subscribed(self) -> frozenset[int]:
        return frozenset(self._subscribed)

    # ---------------------------------------------------------------------------------------------- input

    def receive(self, data: bytes, now: float) -> list[SessionEvent]:
        """Bytes from the transport in, events out. Never raises on any input."""
        return self._route(self.parser.feed(data), now)

    def take_reply(self, exchange: Exchange, data: bytes) -> Packet | None:
        """The fast path of :meth:`receive` for a caller reading its own reply: when ``data`` is exactly the
        final reply of ``exchange`` (the usual chunk on TCP and UDP), complete the exchange and return the
        packet. Anything else returns None and changes nothing: pass the same bytes to :meth:`receive`.

        Why: this one check replaces the parser's buffer, the routing and the event objects of a general
        receive, a good part of what a state query costs the client (docs/performance.md, target 2).
        """
        if self.parser.buffered or exchange.state is not ExchangeState.SENT:
            return None
        cmd = exchange.command
        if self._stale and cmd in self._stale and cmd != _LOOP:
            return None  # a STOP sent past its own marker: the marker takes the first reply (receive())
        head = _SUCCESS_HEADS.get(cmd)
        if head is not None and len(data) == head[2] and data[:_SUCCESS_HEAD_SIZE] == head[0]:
            # Everything up to the data was known before the reply came: only the data's checksum is left.
            if self.parser.verify_checksum and crc16(data[_SUCCESS_HEAD_SIZE:], head[1]):
                return None  # receive() reports the checksum error
            packet = Packet(cmd, data[HEADER_SIZE:-TRAILER_SIZE])
        else:
            whole = whole_packet(data, self.parser.verify_checksum, self.parser.max_payload)
            if whole is None:
                return None
            packet = whole
            payload = packet.payload
            # An E_CMD_PENDING (or a reply without a status) is not final: receive() handles it.
            if packet.command != cmd or len(payload) < 2 or payload[0] | (payload[1] << 8) == _PENDING:
                return None
            if cmd == _LOOP and not _echoes(exchange, payload):
                return None
        if self._active.get(cmd) is not exchange:
            return None
        del self._active[cmd]
        exchange.state = ExchangeState.DONE
        exchange.reply = packet
        if self._stale:
            self._prove(exchange)
        return packet

    def reset_parser(self, now: float) -> list[SessionEvent]:
        """After a silent gap: drop a half-received packet and rescan what the parser held."""
        if not self.parser.buffered:
            return []
        self.parser.reset()
        return self._route(self.parser.feed(b""), now)

    def _route(self, items: list[Packet | ParseEvent], now: float) -> list[SessionEvent]:
        out: list[SessionEvent] = []
        for item in items:
            if isinstance(item, Packet):
                self._on_packet(item, now, out)
            else:
                out.append(item)
                if isinstance(item, ChecksumError):
                    self._on_corrupt(item, out)
        return out

    def _on_packet(self, packet: Packet, now: float, out: list[SessionEvent]) -> None:
        cmd = packet.command
        exchange = self._active.get(cmd)
        if cmd == _LOOP and exchange is not None and not _echoes(exchange, packet.payload):
            exchange = None  # not the echo of the waiting LOOP: a late or duplicated one
        stale = None
        if self._stale and (exchange is None or cmd != _LOOP):  # a LOOP's own echo is its own
            stale = self._stale.get(cmd)
        if stale is not None:
            if stale.expects_final and stale.expires <= now:
                del self._stale[cmd]
            else:
                # The device answers in order: this packet belongs to the abandoned exchange.
                if not stale.expects_final and _is_pending(packet):
                    stale.expects_final = True
                    stale.expires = now + self.stale_final_ttl
                else:
                    del self._stale[cmd]
                out.append(StaleReply(packet, stale.exchange))
                return
        if exchange is not None:
            payload = packet.payload
            first = exchange.state is ExchangeState.SENT
            if len(payload) < 2:
                del self._active[cmd]
                exchange.state = ExchangeState.FAILED
                exchange.error = ProtocolError(
                    f"reply of {len(payload)} bytes has no status code", command=command_name(cmd)
                )
                out.append(ExchangeFailed(exchange, exchange.error))
            elif payload[0] | (payload[1] << 8) == _PENDING:  # _is_pending() inlined: once per reply
                if first:
                    exchange.state = ExchangeState.PENDING
                    exchange.ack = packet
                    out.append(Acknowledged(exchange, packet))
                else:  # a second PENDING for the same exchange: not in the manuals, ignore it
                    out.append(Unsolicited(packet))
                    return
            else:
                del self._active[cmd]
                exchange.state = ExchangeState.DONE
                exchange.reply = packet
                out.append(Completed(exchange, packet))
            if first and self._stale:
                self._prove(exchange)
            return
        out.append(AutoUpdate(packet) if cmd in self._subscribed else Unsolicited(packet))

    def _on_corrupt(self, event: ChecksumError, out: list[SessionEvent]) -> None:
        cmd = event.command
        exchange = self._active.get(cmd)
        if exchange is None or cmd in self._subscribed:
            return
        del self._active[cmd]
        exchange.state = ExchangeState.FAILED
        exchange.error = ProtocolError(
            f"reply failed its checksum (received {event.received:04X}h, computed {event.expected:04X}h)",
            command=command_name(cmd),
        )
        out.append(ExchangeFailed(exchange, exchange.error))


_PENDING = int(Status.E_CMD_PENDING)
_LOOP = int(Cmd.LOOP)
# Ids a stale marker never holds back: LOOP (its replies are told apart by content) and the stops, which must
# go out at once even after an earlier stop was interrupted. A stop's marker still takes the first stop reply
# that comes (the device answers in order, so that is the earlier stop's), the new exchange the next one.
_NEVER_HELD = frozenset({_LOOP, int(Cmd.STOP), int(Cmd.FAST_STOP)})


def _echoes(exchange: Exchange, payload: bytes) -> bool:
    """Whether a LOOP reply payload answers ``exchange``: an error status, or its own data looped back."""
    return len(payload) < 2 or bool(payload[0] | payload[1]) or payload[2:] == exchange.payload


def _reply_max(s: CommandSpec) -> int | None:
    layout = s.reply
    if layout.tail is None:
        return 2 + layout.size
    if layout.tail.max_len is not None:
        return 2 + layout.size + layout.tail.max_len
    return None


# The largest payload (status + data) of each command's reply, from the command table; None: open-ended.
# LOOP's reply echoes at most the 256 bytes a request may carry (WSG manual 4.0.x §3.1.1).
_REPLY_MAX: dict[int, int] = {
    cmd: limit for cmd, s in COMMANDS.items() if (limit := _reply_max(s)) is not None
}
_REPLY_MAX[_LOOP] = 2 + 256


def _success_head(cmd: int, size: int) -> tuple[bytes, int, int]:
    """What a successful reply of ``size`` data bytes starts with, the checksum state after it and the
    whole packet's length: known before the reply comes, so checking a reply is one comparison plus the
    checksum of its data (the state queries' round trip, docs/performance.md, target 2)."""
    head = PREAMBLE + bytes((cmd, (size + 2) & 0xFF, (size + 2) >> 8, 0, 0))  # u16 size, u16 E_SUCCESS
    return head, crc16(head[len(PREAMBLE) :], CRC_AFTER_PREAMBLE), len(head) + size + TRAILER_SIZE


_SUCCESS_HEAD_SIZE = HEADER_SIZE + 2  # the header and the u16 status
# Commands whose successful reply has a fixed size (no variable tail).
_SUCCESS_HEADS: dict[int, tuple[bytes, int, int]] = {
    cmd: _success_head(cmd, s.reply.size) for cmd, s in COMMANDS.items() if s.reply.tail is None
}


def _is_pending(packet: Packet) -> bool:
    p = packet.payload
    return len(p) >= 2 and (p[0] | (p[1] << 8)) == _PENDING
