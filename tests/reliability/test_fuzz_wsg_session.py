"""Fuzzing the decoding paths of issue 13 (long mode: GRIPPERS_FUZZ=long).

* The session's matching against an in-order device behind a hostile line: replies dropped, delayed (and
  everything behind them, as on a TCP stream), duplicated, requests abandoned at random moments, time
  jumping, LOOP barriers when a marker waits for a proof. No exchange may ever complete with another
  request's reply.
* The parser's per-id size bound: with nothing open-ended expected, a false header holds back at most the
  largest fixed reply, whatever the stream.
* The WSG backend's reading of 53h system limits: any 32-bit pattern in any field gives finite, ordered
  limits within the profile's, and a warning for every value it ignored.
"""

from __future__ import annotations

import math
import struct

from hypothesis import given
from hypothesis import strategies as st

from grippers.backends.wsg import _narrow
from grippers.drivers.wsg.commands import Cmd, SystemLimits, decode_reply, encode_reply
from grippers.drivers.wsg.protocol import HEADER_SIZE, TRAILER_SIZE, encode_packet
from grippers.drivers.wsg.session import _REPLY_MAX, Completed, ExchangeState, Session
from grippers.profiles import load_profile

# Commands the device model below answers: a settings read (its value tags the request) and LOOP.
READ = int(Cmd.GET_ACCELERATION)
LOOP = int(Cmd.LOOP)

operation = st.one_of(
    st.tuples(st.just("send"), st.sampled_from([READ, LOOP, int(Cmd.GET_FORCE_LIMIT)])),
    st.tuples(st.just("deliver"), st.integers(1, 4)),
    st.tuples(st.just("drop"), st.just(0)),
    st.tuples(st.just("duplicate"), st.just(0)),
    st.tuples(st.just("abandon"), st.integers(0, 3)),
    st.tuples(st.just("wait"), st.integers(1, 300)),  # tens of ms .. 3 s
)


class _Harness:
    """Plays the client over a :class:`Session`: sends when the slot is free (a barrier when asked),
    reads what the line delivered before every send (the client's drain), abandons at random."""

    def __init__(self) -> None:
        self.s = Session(stale_ttl=0.5)
        self.now = 0.0
        self.tag = 0
        self.expected: dict[int, bytes] = {}  # id(exchange) -> the reply payload its own request gets
        self.exchanges: list = []
        self.line: list[bytes] = []  # replies the device sent, in order, not yet delivered

    def _device(self, cmd: int, payload: bytes) -> bytes:
        self.tag += 1
        if cmd == LOOP:
            return encode_reply(cmd, 0, data=payload)
        if cmd == READ:
            return encode_reply(cmd, 0, acceleration=float(self.tag))
        return encode_reply(cmd, 0, force=float(self.tag))

    def send(self, cmd: int, payload: bytes = b"") -> None:
        self.deliver(len(self.line))  # the drain: what arrived is matched first (all of it, in order)
        if self.s.needs_barrier(cmd, self.now):
            self.send(LOOP, self.s.barrier_payload())
            self.deliver(len(self.line))
        opened = self.s.open(cmd, payload, self.now)
        if opened is None:
            return  # the caller would wait or time out: nothing sent
        exchange, _ = opened
        reply = self._device(cmd, payload)
        self.expected[id(exchange)] = reply
        self.exchanges.append(exchange)
        self.line.append(encode_packet(cmd, reply))

    def deliver(self, n: int) -> None:
        data, self.line = b"".join(self.line[:n]), self.line[n:]
        if not data:
            return
        for ev in self.s.receive(data, self.now):
            if isinstance(ev, Completed):
                assert ev.packet.payload == self.expected[id(ev.exchange)], "a reply went to another request"

    def check(self) -> None:
        for ex in self.exchanges:
            if ex.state is ExchangeState.DONE:
                assert ex.reply.payload == self.expected[id(ex)]
                if ex.command == READ:
                    assert decode_reply(READ, ex.reply.payload).ok


@given(ops=st.lists(operation, max_size=40), loops=st.binary(min_size=1, max_size=4))
def test_fuzz_session_never_hands_a_reply_to_another_request(ops, loops, fuzz_count) -> None:
    fuzz_count["wsg session: matching on a hostile line"] += 1
    h = _Harness()
    for kind, arg in ops:
        if kind == "send":
            h.send(arg, loops + h.tag.to_bytes(2, "little") if arg == LOOP else b"")
        elif kind == "deliver":
            h.deliver(arg)
        elif kind == "drop" and h.line:
            h.line.pop(0)
        elif kind == "duplicate" and h.line:
            h.line.insert(0, h.line[0])  # a repeated packet arrives right behind the original
        elif kind == "abandon":
            waiting = [ex for ex in h.exchanges if not ex.finished]
            if waiting:
                h.s.abandon(waiting[arg % len(waiting)], h.now)
        elif kind == "wait":
            h.now += arg / 100
    h.deliver(len(h.line))
    h.check()


# The most a session holds while no open-ended reply (finger data, device tag) is expected.
FIXED_HOLD = HEADER_SIZE + max(_REPLY_MAX.values()) + TRAILER_SIZE - 1

false_header = st.builds(
    lambda cmd, size: b"\xaa\xaa\xaa" + bytes([cmd]) + struct.pack("<H", size),
    st.integers(0, 0xFF).filter(lambda c: c != 0xAA),
    st.integers(0, 0xFFFF),
)


@given(
    parts=st.lists(false_header | st.binary(max_size=40), max_size=20),
    chunk=st.integers(1, 64),
    subscribed=st.booleans(),
)
def test_fuzz_false_headers_hold_back_at_most_the_largest_fixed_reply(
    parts, chunk, subscribed, fuzz_count
) -> None:
    fuzz_count["wsg parser: per-id size bound"] += 1
    s = Session()
    if subscribed:
        s.subscribe(int(Cmd.GET_WIDTH))
    data = b"".join(parts) + encode_packet(int(Cmd.GET_WIDTH), encode_reply(int(Cmd.GET_WIDTH), 0, width=1.0))
    for i in range(0, len(data), chunk):
        s.receive(data[i : i + chunk], now=0.0)
        assert s.parser.buffered <= FIXED_HOLD


PROFILE = load_profile("wsg50")
word = st.integers(0, 2**32 - 1).map(lambda w: struct.unpack("<f", struct.pack("<I", w))[0])
odd_float = word | st.sampled_from([math.nan, math.inf, -math.inf, 0.0, -0.0, 1e-45, 3.4e38, -1.0])


@given(values=st.lists(odd_float, min_size=8, max_size=8))
def test_fuzz_system_limits_give_finite_ordered_limits(values, fuzz_count) -> None:
    fuzz_count["wsg backend: 53h system limits"] += 1
    device = SystemLimits(*values)
    base = PROFILE.limits()
    limits, warnings = _narrow(base, device, PROFILE.name)
    fields = ("min_width", "max_width", "min_speed", "max_speed", "min_force", "max_force")
    got = [getattr(limits, f) for f in fields]
    assert all(math.isfinite(v) for v in got)
    assert limits.min_width <= limits.max_width and limits.min_speed <= limits.max_speed
    assert limits.min_force <= limits.max_force
    assert base.min_speed <= limits.min_speed and limits.max_speed <= base.max_speed
    assert base.min_force <= limits.min_force and limits.max_force <= base.max_force
    assert limits.max_width <= base.max_width
    used = [v for v in (values[0], values[1], values[2], values[5], values[6])]
    if any(not (math.isfinite(v) and v > 0) for v in used):
        assert warnings
