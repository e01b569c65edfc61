"""Fuzzing the STEPFOC CAN frame decoders and the UART line parser (long mode: GRIPPERS_FUZZ=long).

tests/stepfoc/can/test_can_protocol.py checks ``describe`` never raises and the codecs round-trip;
tests/stepfoc/uart/test_uart_protocol.py checks chunking and garbage around one answer. Here: every command
id with every length 0-8 as data and remote frames against the table's own oracle, typed values that
re-encode to what they decoded from, and the line splitter's recovery after garbage without a newline and
after over-long lines.
"""

from __future__ import annotations

import itertools

from hypothesis import given
from hypothesis import strategies as st

from grippers.drivers.errors import ProtocolError
from grippers.drivers.stepfoc.can_protocol import (
    COMMANDS,
    Cmd,
    FrameLengthError,
    Message,
    decode_frame,
    pack_id,
)
from grippers.drivers.stepfoc.uart_protocol import COMMANDS as UART_COMMANDS
from grippers.drivers.stepfoc.uart_protocol import Line, LineSplitter, LineTooLong, encode_lines


def _check_frame(arbitration_id: int, data: bytes, remote: bool) -> None:
    """The table is the oracle: what decodes, what raises, and which typed error."""
    command = (arbitration_id >> 1) & 0x3F
    spec = COMMANDS.get(command)
    try:
        msg = decode_frame(arbitration_id, data, remote)
    except FrameLengthError as exc:
        assert spec is not None and not remote
        assert len(data) not in spec.lengths
        assert exc.expected == spec.lengths and exc.actual == len(data)
        assert spec.name in str(exc)
        return
    except ProtocolError as exc:
        if not remote and command in (Cmd.TEMPERATURE, Cmd.BUS_VOLTAGE):  # a value outside its range
            value = int.from_bytes(data, "big", signed=True)
            assert value < (-273 if command == Cmd.TEMPERATURE else 0) and "outside" in str(exc), exc
            return
        assert spec is not None and remote and not spec.remote, exc
        return
    assert isinstance(msg, Message)
    assert (msg.node, msg.command, msg.error) == (arbitration_id >> 7, command, bool(arbitration_id & 1))
    if spec is None:
        assert msg.value == bytes(data)
        return
    if remote:
        assert spec.remote and msg.value is None
        return
    assert len(data) in spec.lengths
    layout = spec.layout_for(len(data))
    if command == Cmd.GRIPPER_STATUS:
        assert decode_frame(arbitration_id, layout.encode(msg.value), False).value == msg.value
    elif command not in (Cmd.GRIPPER_COMMAND, Cmd.ERROR_STATE):  # those two have reserved bits
        assert layout.encode(msg.value) == bytes(data)
    assert isinstance(msg.describe(), str)


def test_every_command_id_with_every_length_data_and_remote() -> None:
    """64 ids x 9 lengths x data/remote x error bit x three fill patterns, exhaustively."""
    for command, length, remote, error, fill in itertools.product(
        range(64), range(9), (False, True), (False, True), (0x00, 0xFF, 0x5A)
    ):
        _check_frame(pack_id(7, command, error), bytes([fill]) * length, remote)


@given(
    arbitration_id=st.integers(0, 0x7FF) | st.builds(pack_id, st.integers(0, 15), st.sampled_from(list(Cmd))),
    data=st.binary(max_size=8),
    remote=st.booleans(),
)
def test_fuzz_can_frame_decoder(arbitration_id: int, data: bytes, remote: bool, fuzz_count) -> None:
    fuzz_count["stepfoc CAN frame decoder"] += 1
    _check_frame(arbitration_id, data, remote)


# ------------------------------------------------------------------------------------------ UART lines

MAX_LINE = 256  # the client's default (StepfocUart max_line)


@given(
    garbage=st.binary(max_size=1200),
    newline=st.booleans(),
    value=st.integers(0, 255),
    chunks=st.lists(st.integers(1, 300), max_size=10),
)
def test_fuzz_uart_line_parser_recovers_after_garbage(
    garbage: bytes, newline: bool, value: int, chunks: list[int], fuzz_count
) -> None:
    """Garbage with or without a newline, of any length: bounded buffer, and the next answer line is found."""
    fuzz_count["stepfoc UART line parser"] += 1
    answer = encode_lines([UART_COMMANDS["Grippos"].render(value)])
    stream = garbage + (b"\n" if newline else b"") + b"\n" + answer
    splitter = LineSplitter(MAX_LINE)
    events: list[object] = []
    pos = 0
    for size in chunks:
        events += splitter.feed(stream[pos:pos + size])
        pos += size
        assert splitter.buffered <= MAX_LINE  # an endless line never grows the buffer
    events += splitter.feed(stream[pos:])
    assert splitter.buffered == 0
    for e in events:
        assert isinstance(e, Line | LineTooLong)
        if isinstance(e, Line):
            assert b"\n" not in e.raw and 0 < len(e.raw) <= MAX_LINE
        else:
            assert e.size > MAX_LINE
    last = events[-1]
    assert isinstance(last, Line)
    parsed = UART_COMMANDS["Grippos"].parse(last.text)
    assert parsed is not None and parsed.value == value


@given(data=st.binary(max_size=700), chunks=st.lists(st.integers(1, 90), max_size=12))
def test_fuzz_uart_line_parser_no_newline_never_grows(data: bytes, chunks: list[int], fuzz_count) -> None:
    """A line that never ends (wrong baud rate, a chatty device) is dropped and reported, not buffered."""
    fuzz_count["stepfoc UART line parser: missing newline"] += 1
    data = data.replace(b"\n", b"")
    splitter = LineSplitter(MAX_LINE)
    pos = 0
    for size in chunks + [len(data)]:
        assert splitter.feed(data[pos:pos + size]) == []
        pos += size
        assert splitter.buffered <= MAX_LINE
    events = splitter.feed(b"\n")
    if len(data) > MAX_LINE:
        assert events == [LineTooLong(len(data) + 1)]
    elif data.rstrip(b"\r").strip():
        assert [e.raw for e in events if isinstance(e, Line)] == [data.removesuffix(b"\r")]
