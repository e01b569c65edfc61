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
from grippers.drivers.stepfoc.sim import MsgModel
from grippers.drivers.stepfoc.uart_protocol import COMMANDS as UART_COMMANDS
from grippers.drivers.stepfoc.uart_protocol import (
    GRIPINFO_FIELDS,
    GRIPINFO_RANGES,
    INFO_HEADER,
    INFO_RANGES,
    Line,
    LineSplitter,
    LineTooLong,
    Request,
    encode_lines,
    parse_gripinfo,
    parse_info,
    parser_knows,
)


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
        events += splitter.feed(stream[pos : pos + size])
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
        assert splitter.feed(data[pos : pos + size]) == []
        pos += size
        assert splitter.buffered <= MAX_LINE
    events = splitter.feed(b"\n")
    if len(data) > MAX_LINE:
        assert events == [LineTooLong(len(data) + 1)]
    elif data.rstrip(b"\r").strip():
        assert [e.raw for e in events if isinstance(e, Line)] == [data.removesuffix(b"\r")]


# ------------------------------------------------------------------------------------------ range checks
# Issue 13 item 5: every decoded number is checked against its protocol range. The oracle is the range table.

_SINGLE = [name for name, spec in UART_COMMANDS.items() if spec.lines == 1 and spec.has_value]


@given(name=st.sampled_from(_SINGLE), value=st.integers(-(10**40), 10**40) | st.integers(-300, 3000))
def test_fuzz_uart_single_line_answer_ranges(name: str, value: int, fuzz_count) -> None:
    fuzz_count["stepfoc UART answer ranges"] += 1
    spec = UART_COMMANDS[name]
    line = f"{spec.answer}{value}"
    lo, hi = spec.arg_range
    try:
        answer = spec.parse(line)
    except ProtocolError as exc:
        assert not lo <= value <= hi and "outside" in str(exc) and spec.answer.strip()[:20] in str(exc)
        return
    assert answer is not None and answer.value == value and lo <= value <= hi


@given(
    values=st.fixed_dictionaries(
        {name: st.integers(-(2**33), 2**33) | st.integers(-2, 300) for name, _ in GRIPINFO_FIELDS}
    )
)
def test_fuzz_uart_gripinfo_ranges(values: dict[str, int], fuzz_count) -> None:
    fuzz_count["stepfoc UART Gripinfo ranges"] += 1
    lines = ["I am a gripper"] + [f"{prefix}{values[name]}" for name, prefix in GRIPINFO_FIELDS]
    lo_hi = GRIPINFO_RANGES
    bad = [n for n, _ in GRIPINFO_FIELDS if not lo_hi[n][0] <= values[n] <= lo_hi[n][1]]  # in line order
    try:
        info = parse_gripinfo(lines)
    except ProtocolError as exc:
        assert bad and bad[0] in str(exc)  # the first bad line is the one named
        return
    assert not bad and all(int(getattr(info, n)) == v for n, v in values.items())


@given(
    header=st.lists(st.integers(-5, 300), min_size=4, max_size=4),
    vbus=st.integers(-(10**7), 10**7),
    temperature=st.floats(allow_nan=True, allow_infinity=True, width=32),
)
def test_fuzz_uart_info_ranges(header: list[int], vbus: int, temperature: float, fuzz_count) -> None:
    fuzz_count["stepfoc UART Info ranges"] += 1
    lines = [f"{prefix}{v}" for (_, prefix), v in zip(INFO_HEADER, header, strict=True)]
    lines += [f"Vbus voltage: {vbus} mV", f"Temperature is:{temperature:.2f} Degrees"]
    try:
        info = parse_info(lines)
    except ProtocolError as exc:
        assert "outside" in str(exc)
        return
    for (name, _), v in zip(INFO_HEADER, header, strict=True):
        lo, hi = INFO_RANGES[name]
        assert lo <= v <= hi and getattr(info, name) == v
    assert 0 <= vbus <= INFO_RANGES["vbus_mv"][1]


# ------------------------------------------------------------------------------------------ firmware model
# Issue 12 §1: random raw frames to the model at random times; the firmware's rules hold after every step.

_FRAME = st.one_of(
    st.tuples(st.just(Cmd.GRIPPER_COMMAND), st.binary(min_size=5, max_size=5), st.just(False)),
    st.tuples(st.just(Cmd.GRIPPER_COMMAND), st.just(b""), st.just(False)),
    st.tuples(
        st.sampled_from([Cmd.ESTOP, Cmd.CLEAR_ERROR, Cmd.IDLE, Cmd.GRIPPER_CALIBRATE]),
        st.just(b""),
        st.just(False),
    ),
    st.tuples(st.just(Cmd.WATCHDOG), st.binary(min_size=5, max_size=5), st.just(False)),
    st.tuples(st.just(Cmd.ERROR_STATE), st.just(b""), st.just(True)),
)


@given(steps=st.lists(st.tuples(_FRAME, st.floats(0.0, 3.0)), max_size=25), part=st.booleans())
def test_fuzz_msg_model_follows_the_firmware_rules(steps, part: bool, fuzz_count) -> None:
    fuzz_count["stepfoc firmware model (raw frames)"] += 1
    m = MsgModel(node=2, part_width_mm=40.0 if part else None)
    t = 0.0
    idle_since_stop = False
    ever_calibrated = False
    for (command, data, remote), dt in steps:
        t += dt
        m.advance(t)
        flag_before = m.status(t).estop_error
        replies = m.handle_frame(pack_id(2, command), data, remote, t)
        for r in replies:
            assert 0 <= r.arbitration_id <= 0x7FF and len(r.data) <= 8
            assert bool(r.arbitration_id & 1) == m.error_active  # the error bit in every identifier
        if command == Cmd.GRIPPER_COMMAND and len(data) == 5:
            idle_since_stop = False
        elif command in (Cmd.CLEAR_ERROR, Cmd.IDLE, Cmd.ESTOP):
            idle_since_stop = True
        elif command == Cmd.GRIPPER_CALIBRATE and m.calibrating:
            idle_since_stop = False  # calibration moves the jaws
        if command == Cmd.ESTOP:
            # only the driver's e-stop error: the 60 frame's flag is what it was
            assert m.error_state().estop and m.status(t).estop_error == flag_before
        ticks, calibrating = m.ticks, m.calibrating
        m.advance(t + 1.0)
        t += 1.0
        if idle_since_stop and not calibrating:
            assert m.ticks == ticks  # after 0, 1 or 12 nothing moves until a new 5-byte 61
        if calibrating and not m.calibrating:
            idle_since_stop = True  # the end of a calibration idles the driver too
        if ever_calibrated:
            assert m.calibrated  # no command here clears it (only reset and the calibration time-out)
        ever_calibrated = ever_calibrated or m.calibrated
        assert m.error_state().calibrated  # frame 26 byte 1: the driver's factory calibration


@given(name=st.from_regex(r"[A-Za-z][A-Za-z0-9_]{0,12}", fullmatch=True), arg=st.none() | st.integers(0, 999))
def test_fuzz_uart_sim_answers_only_what_the_parser_knows(name: str, arg: int | None, fuzz_count) -> None:
    fuzz_count["stepfoc UART simulator dispatch"] += 1
    from grippers.drivers.stepfoc.sim.uart_server import UartSimServer

    req = Request(name, None if arg is None else str(arg))
    answer = UartSimServer.answer(_FakeServer(), req, 1.0)  # type: ignore[arg-type]
    if not parser_knows(req):
        assert answer is None
    else:
        assert answer is None or all(isinstance(x, str) for x in answer)


class _FakeServer:
    """The attributes UartSimServer.answer reads, around a real model (no pty needed)."""

    def __init__(self) -> None:
        from grippers.drivers.stepfoc.sim.uart_server import UartSimServer

        self.model = MsgModel()
        self.unknown_reply = "Unknown command"
        self.gripinfo = lambda: UartSimServer.gripinfo(self)  # type: ignore[arg-type]
        self.info = lambda: UartSimServer.info(self)  # type: ignore[arg-type]
