"""The sans-IO UART text protocol: formatting, line splitting, answer parsing, the device-side receiver."""

from __future__ import annotations

import pytest
from hypothesis import given
from hypothesis import strategies as st

from grippers.drivers.errors import LimitError, ProtocolError
from grippers.drivers.stepfoc.can_protocol import Detection
from grippers.drivers.stepfoc.uart_protocol import (
    COMMANDS,
    GripInfo,
    GripInfoAssembler,
    InfoAssembler,
    Line,
    LineSplitter,
    LineTooLong,
    Rejected,
    Request,
    UartInfo,
    atoi,
    encode_lines,
    format_command,
    is_unknown_command,
    parse_answer,
    parse_gripinfo,
    parse_info,
    render_gripinfo,
    render_info,
)
from grippers.drivers.stepfoc.uart_protocol import (
    CommandReceiver as Receiver,
)

# ---- formatting ------------------------------------------------------------------------------------------


@pytest.mark.parametrize(
    ("name", "value", "wire"),
    [
        ("Grippos", None, b"#Grippos\n"),
        ("Grippos", 200, b"#Grippos 200\n"),
        ("Gripvel", 0, b"#Gripvel 0\n"),
        ("Gripcur", 1000, b"#Gripcur 1000\n"),
        ("Gripact", True, b"#Gripact 1\n"),
        ("Gripstop", 0, b"#Gripstop 0\n"),
        ("Gripper", 1, b"#Gripper 1\n"),
        ("Gripcal", None, b"#Gripcal\n"),
        ("Gripinfo", None, b"#Gripinfo\n"),
        ("Info", None, b"#Info\n"),
        ("Somethingnew", 5, b"#Somethingnew 5\n"),  # names outside the table pass (probing)
    ],
)
def test_format_command(name: str, value: int | None, wire: bytes) -> None:
    assert format_command(name, value) == wire


@pytest.mark.parametrize(
    ("name", "value"),
    [
        ("Grippos", 256),
        ("Grippos", -1),
        ("Gripvel", 300),
        ("Gripact", 2),
        ("Gripstop", -1),
        ("Gripper", 7),
        ("Gripcur", 2801),
    ],
)
def test_format_refuses_out_of_range(name: str, value: int) -> None:
    with pytest.raises(LimitError) as err:
        format_command(name, value)
    assert err.value.command == name


@pytest.mark.parametrize(("name", "value"), [("Gripcal", 1), ("Gripinfo", 0), ("Info", 3)])
def test_format_refuses_argument_for_actions(name: str, value: int) -> None:
    with pytest.raises(ValueError, match="takes no argument"):
        format_command(name, value)


@pytest.mark.parametrize("name", ["", "Grip pos", "#Grippos", "Grippos\n", "1abc", "Gr\u00fcppos", "a-b"])
def test_format_refuses_invalid_names(name: str) -> None:
    with pytest.raises(ValueError):
        format_command(name)


def test_format_length_limit_counts_name_and_argument() -> None:
    # 20 characters of name + argument is the most the firmware takes (docs/protocols.md §2)
    assert format_command("A" * 15, 12345) == b"#" + b"A" * 15 + b" 12345\n"
    with pytest.raises(LimitError):
        format_command("A" * 16, 12345)
    with pytest.raises(LimitError):
        format_command("A" * 20)  # a name longer than 19 characters never reaches the dispatcher
    with pytest.raises(ValueError):
        format_command("Grippos", "12")  # type: ignore[arg-type]


# ---- single-line answers ---------------------------------------------------------------------------------

ANSWERS = [
    ("Gripper: 1", "Gripper", 1),
    ("Gripper calibration! ", "Gripcal", None),
    ("Gripper current position is: 127", "Grippos", 127),
    ("Gripper velocity setpoint is: 50", "Gripvel", 50),
    ("Gripper current setpoint is: 600", "Gripcur", 600),
    ("Gripper activation bit is: 0", "Gripact", 0),
    ("Gripper estop bit is: 1", "Gripstop", 1),
    ("Clear errors", "Clear", None),
]


@pytest.mark.parametrize(("line", "command", "value"), ANSWERS)
def test_parse_each_answer(line: str, command: str, value: int | None) -> None:
    ans = COMMANDS[command].parse(line)
    assert ans is not None and ans.command == command and ans.value == value
    assert parse_answer(line) == ans
    # the simulator prints through the same row
    assert COMMANDS[command].render(value) == line


@pytest.mark.parametrize(("line", "command", "value"), ANSWERS)
def test_other_rows_do_not_claim_an_answer(line: str, command: str, value: int | None) -> None:
    for name, spec in COMMANDS.items():
        if name != command:
            assert spec.parse(line) is None, name


@pytest.mark.parametrize(
    "line",
    [
        "Gripper: ",
        "Gripper: x",
        "Gripper:1",
        "Gripper current position is: 1.5",
        "gripper: 1",
        "Gripper calibration",
        "Unknown command",
    ],
)
def test_malformed_answers_are_not_parsed(line: str) -> None:
    assert parse_answer(line) is None


def test_unknown_command_recognised() -> None:
    assert is_unknown_command("Unknown command")
    assert is_unknown_command("Unknown command ")
    assert not is_unknown_command("Unknown commander")


def test_calibration_answer_tolerates_missing_trailing_blank() -> None:
    assert COMMANDS["Gripcal"].parse("Gripper calibration!") is not None
    assert encode_lines([COMMANDS["Gripcal"].render()]) == b"Gripper calibration! \r\n"


# ---- Gripinfo ---------------------------------------------------------------------------------------------

GRIPINFO_LINES = [
    "I am a gripper",
    "Gripper calibrated is: 1",
    "Gripper activated is: 1",
    "Gripper position setpoint is: 200",
    "Gripper speed setpoint is: 100",
    "Gripper current setpoint is: 500",
    "Gripper estop status: 0",
    "Gripper action status: 1",
    "Gripper object detection status: 1",
    "Gripper max open position: -1234",
    "Gripper max closed position: 56789",
]


def test_parse_gripinfo() -> None:
    info = parse_gripinfo(GRIPINFO_LINES)
    assert info == GripInfo(
        is_gripper=True,
        calibrated=True,
        activated=True,
        position_setpoint=200,
        speed_setpoint=100,
        current_setpoint=500,
        estop=False,
        action=True,
        detection=Detection.CLOSING_OBJECT,
        max_open_position=-1234,
        max_closed_position=56789,
    )
    assert render_gripinfo(info) == GRIPINFO_LINES


def test_gripinfo_not_a_gripper_and_out_of_range_detection() -> None:
    info = parse_gripinfo(["I am not a gripper ", *GRIPINFO_LINES[1:]])
    assert info.is_gripper is False and isinstance(info.detection, Detection)
    assert render_gripinfo(info)[0] == "I am not a gripper "
    odd = "Gripper object detection status: 7"  # issue 13 item 5: a value outside 0..3 is not kept
    with pytest.raises(ProtocolError, match="detection 7 outside 0..3 in the line 'Gripper object detection"):
        parse_gripinfo(["I am not a gripper ", *GRIPINFO_LINES[1:8], odd, *GRIPINFO_LINES[9:]])


def test_gripinfo_rejects_incomplete_or_disordered() -> None:
    with pytest.raises(ProtocolError):
        parse_gripinfo(GRIPINFO_LINES[:-1])
    swapped = GRIPINFO_LINES[:]
    swapped[2], swapped[3] = swapped[3], swapped[2]
    with pytest.raises(ProtocolError):
        parse_gripinfo(swapped)


def test_gripinfo_assembler_resynchronises() -> None:
    asm = GripInfoAssembler()
    stream = ["noise", *GRIPINFO_LINES[:5], "garbage in the middle", *GRIPINFO_LINES]
    results = [r for r in (asm.feed(line) for line in stream) if r is not None]
    assert results == [parse_gripinfo(GRIPINFO_LINES)]
    assert asm.discarded == 1 + 5 + 1


def test_gripinfo_restarts_on_a_new_first_line() -> None:
    asm = GripInfoAssembler()
    stream = [*GRIPINFO_LINES[:4], *GRIPINFO_LINES]
    results = [r for r in (asm.feed(line) for line in stream) if r is not None]
    assert len(results) == 1 and asm.discarded == 4


# ---- Info -------------------------------------------------------------------------------------------------

# what the public firmware prints (communication.cpp), thermistor off
INFO_LINES = [
    "Hardware version: 3",
    "Batch date: 12",
    "Software version: 21",
    "CAN ID is: 5",
    "Calibrated",
    "Termistor is disabled",
    "Vbus voltage: 24012 mV",
    "Phase direction: 1",
    "Phase Order: 0",
    "Number of pole pairs: 7",
    "Single phase resistance: 0.48000",
    "Single phase Inductance: 0.00021",
    "Kt: 0.05000",
    "KV: 190.00000",
]


def test_parse_info() -> None:
    info = parse_info(INFO_LINES)
    assert (info.hardware_version, info.batch_date, info.software_version, info.can_id) == (3, 12, 21, 5)
    assert info.calibrated is True and info.thermistor_enabled is False and info.temperature_c is None
    assert info.vbus_mv == 24012 and info.pole_pairs == 7 and info.phase_direction == 1
    assert info.kv == pytest.approx(190.0) and info.inductance == pytest.approx(0.00021)
    assert info.unknown_lines == ()
    assert render_info(info) == INFO_LINES


def test_info_temperature_and_unknown_status_lines_kept() -> None:
    extra = ["Not calibrated", "Temperature is:31.50 Degrees", "Fancy new line: 3", "Vbus voltage: x mV"]
    lines = [*INFO_LINES[:4], *extra]
    info = parse_info(lines)
    assert info.calibrated is False and info.thermistor_enabled is True
    assert info.temperature_c == pytest.approx(31.5)
    assert info.unknown_lines == ("Fancy new line: 3", "Vbus voltage: x mV")
    assert parse_info(render_info(info)) == info


def test_info_header_only_is_enough() -> None:
    info = parse_info(INFO_LINES[:4])
    assert info == UartInfo(3, 12, 21, 5)


def test_info_incomplete_header() -> None:
    with pytest.raises(ProtocolError):
        parse_info(INFO_LINES[:3])
    with pytest.raises(ProtocolError):
        parse_info([INFO_LINES[1], *INFO_LINES])  # a stray line before the answer


def test_info_assembler_skips_garbage_before_header() -> None:
    asm = InfoAssembler()
    for line in ["Gripper: 1", "\ufffd\ufffd", "Hardware version: 9", "Batch date: zz", *INFO_LINES]:
        asm.feed(line)
    assert asm.finish() == parse_info(INFO_LINES)
    assert asm.discarded == 4


@given(
    st.builds(
        UartInfo,
        hardware_version=st.integers(0, 255),
        batch_date=st.integers(0, 255),
        software_version=st.integers(0, 255),
        can_id=st.integers(0, 15),
        calibrated=st.none() | st.booleans(),
        vbus_mv=st.none() | st.integers(0, 60000),
        pole_pairs=st.none() | st.integers(1, 50),
        kt=st.none() | st.integers(0, 10**7).map(lambda n: n / 100000),
    )
)
def test_info_round_trip(info: UartInfo) -> None:
    assert parse_info(render_info(info)) == info


# ---- line splitter ----------------------------------------------------------------------------------------


def _texts(events: list) -> list[str]:
    return [e.text for e in events if isinstance(e, Line)]


def test_splitter_crlf_lf_and_blank_lines() -> None:
    sp = LineSplitter()
    assert _texts(sp.feed(b"Gripper: 1\r\nGripper: 0\n\r\n\nGripper calibration! \r\n")) == [
        "Gripper: 1",
        "Gripper: 0",
        "Gripper calibration! ",
    ]


def test_splitter_missing_newline_waits_then_reset_drops() -> None:
    sp = LineSplitter()
    assert sp.feed(b"Gripper: 1") == []
    assert sp.buffered == 10
    assert sp.reset() == b"Gripper: 1"
    assert _texts(sp.feed(b"Gripper: 0\r\n")) == ["Gripper: 0"]


def test_splitter_drops_overlong_lines_with_an_event() -> None:
    sp = LineSplitter(max_line=32)
    events = sp.feed(b"x" * 100)
    assert events == [] and sp.buffered == 0
    events = sp.feed(b"yyy\r\nGripper: 1\r\n")
    assert events[0] == LineTooLong(105) and _texts(events) == ["Gripper: 1"]
    events = sp.feed(b"z" * 33 + b"\nGripper: 0\n")
    assert isinstance(events[0], LineTooLong) and _texts(events) == ["Gripper: 0"]


def test_splitter_non_utf8() -> None:
    (event,) = LineSplitter().feed(b"\xff\xfeGripper: 1\r\n")
    assert isinstance(event, Line) and event.raw == b"\xff\xfeGripper: 1"
    assert parse_answer(event.text) is None  # garbage in front: not an answer


@given(st.binary(max_size=300), st.lists(st.integers(1, 40), max_size=20))
def test_splitter_any_bytes_any_chunks(data: bytes, cuts: list[int]) -> None:
    """Never raises; the buffer stays bounded; chunking never changes the lines found."""
    whole = LineSplitter(max_line=64).feed(data)
    sp = LineSplitter(max_line=64)
    got: list = []
    pos = 0
    for cut in cuts:
        got += sp.feed(data[pos : pos + cut])
        pos += cut
        assert sp.buffered <= 64 + 40
    got += sp.feed(data[pos:])
    assert _texts(got) == _texts(whole)
    for e in got:
        if isinstance(e, Line):
            assert len(e.raw) <= 64 and b"\n" not in e.raw


@given(st.binary(max_size=80), st.binary(max_size=80), st.integers(0, 255))
def test_answers_survive_garbage_around_them(before: bytes, after: bytes, value: int) -> None:
    """A valid answer on its own line is found whatever noise surrounds it."""
    answer = encode_lines([COMMANDS["Grippos"].render(value)])
    events = LineSplitter(max_line=128).feed(before + b"\n" + answer + after)
    parsed = [COMMANDS["Grippos"].parse(t) for t in _texts(events)]
    assert any(p is not None and p.value == value for p in parsed)


@given(st.text(max_size=60))
def test_parsers_never_raise_on_text(text: str) -> None:
    parse_answer(text)
    GripInfoAssembler().feed(text)
    InfoAssembler().feed(text)


# ---- device-side receiver ---------------------------------------------------------------------------------


def test_receiver_gets_and_sets() -> None:
    rx = Receiver()
    assert rx.feed(b"#Grippos\n#Grippos 200\r\n#Gripvel  7 \n") == [
        Request("Grippos", None),
        Request("Grippos", "200"),
        Request("Gripvel", "7"),
    ]


def test_receiver_hash_resets_and_split_chunks() -> None:
    rx = Receiver()
    assert rx.feed(b"noise#Grip") == []
    assert rx.feed(b"#Gripinfo") == []
    assert rx.feed(b"\n") == [Request("Gripinfo", None)]
    out = rx.feed(b"noise only\n")
    assert out == [Rejected(b"noise only\n", "no '#' at the start")]


def test_receiver_length_limits() -> None:
    rx = Receiver()
    (r,) = rx.feed(b"#AAAAAAAAAAAAAAA 123456\n")
    assert isinstance(r, Rejected)
    # bytes beyond the buffer are dropped, the newline included: only the next '#' recovers
    assert rx.feed(b"#" + b"x" * 100 + b"\n") == []
    assert rx.feed(b"#Gripper\n") == [Request("Gripper", None)]


@pytest.mark.parametrize(("text", "value"), [("12", 12), ("  -5x", -5), ("abc", 0), ("", 0), ("+7", 7)])
def test_atoi(text: str, value: int) -> None:
    assert atoi(text) == value


@given(st.binary(max_size=200))
def test_receiver_never_raises(data: bytes) -> None:
    rx = Receiver()
    for item in rx.feed(data):
        assert isinstance(item, Request | Rejected)
