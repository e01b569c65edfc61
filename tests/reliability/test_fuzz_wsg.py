"""Fuzzing the WSG packet parser and the reply/request decoders (long mode: GRIPPERS_FUZZ=long).

tests/wsg/core/test_wsg_protocol.py already shows that chunking never changes what is parsed and that
noise between packets loses none; these properties add mutated valid streams (bit flips, insertions,
deletions, cut packets), the bound on what the parser holds, recovery with and without a silent gap, and
the typed errors of every reply and request layout.
"""

from __future__ import annotations

import struct

from hypothesis import given
from hypothesis import strategies as st

from grippers.drivers.errors import ProtocolError
from grippers.drivers.wsg.commands import COMMANDS, RequestFormatError, decode_reply, decode_request
from grippers.drivers.wsg.protocol import (
    HEADER_SIZE,
    MAX_PAYLOAD,
    TRAILER_SIZE,
    BadLength,
    ChecksumError,
    Discarded,
    Packet,
    PacketParser,
    Status,
    encode_packet,
)

EVENT_TYPES = (Packet, ChecksumError, BadLength, Discarded)
# The most a parser may hold: one candidate packet of the largest size it accepts, less its last byte.
HOLD_BOUND = HEADER_SIZE + MAX_PAYLOAD + TRAILER_SIZE - 1
SMALL = 64  # max_payload of the mutated-stream parser: the same logic, 16x less padding per example
SENTINEL = encode_packet(0x06, b"sentinel \x00\xaa\xaa\xaa\xff")

packets = st.builds(
    encode_packet,
    st.integers(0, 0xFF).filter(lambda c: c != 0xAA),  # id 0xAA cannot be framed (docs/protocols.md §1)
    st.binary(max_size=48),
)
mutation = st.tuples(
    st.sampled_from(["flip", "insert", "delete", "cut", "preamble"]),
    st.integers(0, 2**16),
    st.binary(min_size=1, max_size=6),
)


def _mutate(stream: bytes, edits: list[tuple[str, int, bytes]]) -> bytes:
    buf = bytearray(stream)
    for kind, where, data in edits:
        i = where % (len(buf) + 1)
        if kind == "flip" and buf:
            buf[i % len(buf)] ^= data[0] or 1
        elif kind == "insert":
            buf[i:i] = data
        elif kind == "delete":
            del buf[i : i + len(data)]
        elif kind == "cut":  # the rest of the stream lost: a half packet
            del buf[i:]
        elif kind == "preamble":  # a false preamble with a plausible or absurd size field
            buf[i:i] = b"\xaa\xaa\xaa" + data[:3]
    return bytes(buf)


def _feed(parser: PacketParser, data: bytes, chunks: list[int], bound: int = HOLD_BOUND) -> list[object]:
    out: list[object] = []
    pos = 0
    for size in chunks or [len(data) or 1]:
        out += parser.feed(data[pos : pos + size])
        pos += size
        assert parser.buffered <= bound  # never stalls on an unbounded buffer
    out += parser.feed(data[pos:])
    assert parser.buffered <= bound
    return out


@given(
    valid=st.lists(packets, min_size=1, max_size=6),
    edits=st.lists(mutation, max_size=6),
    chunks=st.lists(st.integers(1, 64), max_size=12),
)
def test_fuzz_parser_mutated_stream_recovers_on_next_valid_packet(
    valid: list[bytes], edits: list[tuple[str, int, bytes]], chunks: list[int], fuzz_count
) -> None:
    """Only documented events come out, and a valid packet after the damage is found without a gap."""
    fuzz_count["wsg parser: mutated stream, recovery without a gap"] += 1
    damaged = _mutate(b"".join(valid), edits)
    parser = PacketParser(max_payload=SMALL)
    # Enough trailing bytes to complete any false candidate (its checksum then fails and the scan resumes).
    padding = bytes(SMALL + HEADER_SIZE + TRAILER_SIZE)
    out = _feed(parser, damaged + SENTINEL + padding, chunks, HEADER_SIZE + SMALL + TRAILER_SIZE - 1)
    assert all(isinstance(e, EVENT_TYPES) for e in out)
    found = [e for e in out if isinstance(e, Packet)]
    sentinel = Packet(0x06, SENTINEL[HEADER_SIZE:-TRAILER_SIZE])
    # A false candidate swallows the sentinel only if its random checksum matches (p = 2^-16): then it
    # is itself a packet that was never sent.
    sent = {Packet(p[3], p[HEADER_SIZE:-TRAILER_SIZE]) for p in valid} | {sentinel}
    assert sentinel in found or any(p not in sent for p in found)


@given(garbage=st.binary(max_size=600), chunks=st.lists(st.integers(1, 80), max_size=12))
def test_fuzz_parser_garbage_then_silent_gap_then_packet(
    garbage: bytes, chunks: list[int], fuzz_count
) -> None:
    """After any garbage and the silent-gap resets, the next packet is parsed alone and exactly."""
    fuzz_count["wsg parser: garbage, silent gap, packet"] += 1
    parser = PacketParser()
    out = _feed(parser, garbage, chunks)
    while parser.buffered:
        before = parser.buffered
        parser.reset()
        out += parser.feed(b"")
        assert parser.buffered < before  # every reset makes progress: no stall
    assert all(isinstance(e, EVENT_TYPES) for e in out)
    assert parser.feed(SENTINEL) == [Packet(0x06, SENTINEL[HEADER_SIZE:-TRAILER_SIZE])]


# ---------------------------------------------------------------------------------------- reply decoders


def _fixed_size(cmd: int) -> tuple[int, bool, int | None]:
    layout = COMMANDS[cmd].reply
    return layout.size, layout.tail is not None, layout.tail.max_len if layout.tail is not None else None


@given(
    cmd=st.sampled_from(sorted(COMMANDS)),
    data=st.binary(max_size=80),
    status=st.just(0) | st.integers(0, 0xFFFF),
)
def test_fuzz_reply_decoders_give_typed_errors(cmd: int, data: bytes, status: int, fuzz_count) -> None:
    """Truncated or oversized success data is a ProtocolError naming the command; errors carry no data."""
    fuzz_count["wsg reply decoders"] += 1
    payload = struct.pack("<H", status) + data
    size, variable, max_len = _fixed_size(cmd)
    if status != Status.E_SUCCESS:
        reply = decode_reply(cmd, payload)
        assert int(reply.status) == status and reply.fields == {} and reply.value is None
        return
    fits = len(data) == size if not variable else size <= len(data) <= size + (max_len or len(data))
    try:
        reply = decode_reply(cmd, payload)
    except ProtocolError as exc:
        assert not fits, exc
        assert COMMANDS[cmd].name in str(exc)
        assert "data bytes" in exc.message or "exceeds" in exc.message
    else:
        assert fits
        assert reply.ok and set(reply.fields) == set(COMMANDS[cmd].reply.names)
        reply.value  # noqa: B018 - the typed aggregate builds from any decodable data


@given(cmd=st.integers(0, 0xFF), payload=st.binary(max_size=1))
def test_fuzz_reply_without_status_is_a_protocol_error(cmd: int, payload: bytes, fuzz_count) -> None:
    fuzz_count["wsg reply decoders: no status"] += 1
    try:
        decode_reply(cmd, payload)
    except ProtocolError as exc:
        assert "no status code" in exc.message
    else:
        raise AssertionError("a reply without a status code decoded")


@given(cmd=st.integers(0, 0xFF), payload=st.binary(max_size=300))
def test_fuzz_request_decoder_names_the_status_the_device_answers(
    cmd: int, payload: bytes, fuzz_count
) -> None:
    """What the simulator (and the monitor) decode: fields, or the status code a WSG answers with."""
    fuzz_count["wsg request decoders"] += 1
    try:
        fields = decode_request(cmd, payload)
    except RequestFormatError as exc:
        assert exc.status in (Status.E_CMD_UNKNOWN, Status.E_NO_PARAM_EXPECTED, Status.E_CMD_FORMAT_ERROR)
        if cmd not in COMMANDS:
            assert exc.status == Status.E_CMD_UNKNOWN
    else:
        assert cmd in COMMANDS and set(fields) == set(COMMANDS[cmd].request.names)
