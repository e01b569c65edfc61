"""The round trip's fast paths against the general ones they shortcut (long mode: GRIPPERS_FUZZ=long).

A state query's reply is checked by ``Session.take_reply`` (``whole_packet`` or a precomputed success header)
and decoded by ``reply_value`` instead of the parser's scan, the session's routing and ``decode_reply``
(docs/performance.md, target 2). A shortcut is correct only if it never disagrees with the path it skips:
these properties feed both the same bytes, valid, mutated and foreign.
"""

from __future__ import annotations

import struct

from hypothesis import given
from hypothesis import strategies as st

from grippers.drivers.errors import ProtocolError
from grippers.drivers.wsg.commands import COMMANDS, decode_reply, encode_reply, reply_value
from grippers.drivers.wsg.protocol import PacketParser, Status, encode_packet, whole_packet
from grippers.drivers.wsg.session import Completed, ExchangeState, Session

STATE_QUERIES = (0x40, 0x41, 0x43, 0x44, 0x45)
commands = st.sampled_from(sorted(COMMANDS))


def _reply(cmd: int, status: int, data: bytes) -> bytes:
    return encode_packet(cmd, struct.pack("<H", status) + data)


def _success(cmd: int) -> bytes:
    layout = COMMANDS[cmd].reply
    return encode_packet(
        cmd,
        encode_reply(cmd, 0, **{n: 0 for n in layout.names})
        if not layout.tail
        else b"\x00\x00" + bytes(layout.size),
    )


@st.composite
def chunks(draw: st.DrawFn, cmd: int) -> bytes:
    """What a caller may read after asking for ``cmd``: its reply in any status, other ids, damage, noise."""
    kind = draw(st.sampled_from(["success", "status", "other", "mutated", "two", "noise"]))
    if kind == "success":
        return _success(cmd)
    if kind == "status":
        status = draw(st.sampled_from([int(Status.E_CMD_PENDING), 1, 0x1A]) | st.integers(0, 0xFFFF))
        return _reply(cmd, status, draw(st.binary(max_size=12)))
    if kind == "other":
        return _success(draw(commands))
    if kind == "two":
        return _success(cmd) + _success(draw(commands))
    if kind == "noise":
        return draw(st.binary(max_size=40))
    raw = bytearray(_success(cmd))
    i = draw(st.integers(0, len(raw) - 1))
    raw[i] ^= draw(st.integers(1, 255))
    return bytes(raw[: draw(st.integers(0, len(raw)))]) if draw(st.booleans()) else bytes(raw)


@given(data=st.binary(max_size=40) | commands.map(_success), verify=st.booleans())
def test_fuzz_whole_packet_agrees_with_the_scan(data: bytes, verify: bool, fuzz_count) -> None:
    """A packet from ``whole_packet`` is exactly what the parser's scan finds in the same bytes."""
    fuzz_count["wsg fast path: whole_packet"] += 1
    packet = whole_packet(data, verify)
    if packet is None:
        return
    parser = PacketParser(verify_checksum=verify)
    # Fed in two pieces, the parser cannot take its own whole-packet shortcut: this is the scan.
    assert parser.feed(data[:1]) + parser.feed(data[1:]) == [packet]
    assert parser.buffered == 0


def _plain(events: list[object]) -> list[tuple[str, object]]:
    """Events without their exchange objects, which belong to one session each."""
    out: list[tuple[str, object]] = []
    for e in events:
        error = getattr(e, "error", None)
        out.append((type(e).__name__, str(error) if error else getattr(e, "packet", e)))
    return out


@given(data=st.data(), cmd=commands, verify=st.booleans())
def test_fuzz_take_reply_agrees_with_receive(data: st.DataObject, cmd: int, verify: bool, fuzz_count) -> None:
    """Where take_reply accepts bytes, receive() completes the same exchange with the same packet; where it
    declines, nothing changed and receive() still gets the whole story."""
    fuzz_count["wsg fast path: take_reply"] += 1
    chunk = data.draw(chunks(cmd))
    fast, slow = Session(verify_checksum=verify), Session(verify_checksum=verify)
    ex_fast, _ = fast.send(cmd, b"", now=0.0)
    ex_slow, _ = slow.send(cmd, b"", now=0.0)
    packet = fast.take_reply(ex_fast, chunk)
    events = slow.receive(chunk, now=0.0)
    if packet is None:
        assert ex_fast.state is ExchangeState.SENT and fast.is_busy(cmd, 0.0)
        assert _plain(fast.receive(chunk, now=0.0)) == _plain(events)  # declining lost nothing
        assert ex_fast.state is ex_slow.state
        return
    assert events == [Completed(ex_slow, packet)]
    assert ex_fast.state is ex_slow.state is ExchangeState.DONE
    assert ex_fast.reply == ex_slow.reply == packet and not fast.is_busy(cmd, 0.0)


@given(
    cmd=commands | st.integers(0, 0xFF),
    payload=st.binary(max_size=40) | commands.map(lambda c: _success(c)[6:-2]),
)
def test_fuzz_reply_value_agrees_with_decode_reply(cmd: int, payload: bytes, fuzz_count) -> None:
    fuzz_count["wsg fast path: reply_value"] += 1
    try:
        expected = decode_reply(cmd, payload).value
    except ProtocolError as exc:
        try:
            reply_value(cmd, payload)
        except ProtocolError as fast:
            assert fast.message == exc.message
        else:
            raise AssertionError("reply_value decoded what decode_reply refuses") from None
        return
    assert reply_value(cmd, payload) == expected


def test_state_queries_take_the_precomputed_header() -> None:
    """The width, speed and force replies are the ones the header shortcut exists for."""
    for cmd in STATE_QUERIES:
        s = Session()
        ex, _ = s.send(cmd, b"\x00\x00\x00", now=0.0)
        assert s.take_reply(ex, _success(cmd)) == ex.reply
        assert ex.state is ExchangeState.DONE
