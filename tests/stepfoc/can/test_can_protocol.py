"""The CAN codec: identifiers, every command's layout, bit order, and wrong lengths (docs/protocols.md §2)."""

from __future__ import annotations

import pytest
from hypothesis import given
from hypothesis import strategies as st

from grippers.drivers.errors import LimitError, ProtocolError
from grippers.drivers.stepfoc.can_protocol import (
    COMMANDS,
    CanFrame,
    Cmd,
    Detection,
    DeviceInfo,
    Direction,
    EncoderData,
    ErrorState,
    FrameLengthError,
    GripperCommand,
    GripperStatus,
    Watchdog,
    WatchdogAction,
    decode_command,
    decode_frame,
    decode_status,
    describe,
    encode_command,
    encode_frame,
    encode_status,
    pack_id,
    unpack_id,
)

from ..strategies import STATUS_FIELDS

commands = st.builds(
    GripperCommand,
    position=st.integers(0, 255),
    speed=st.integers(0, 255),
    current_ma=st.integers(-32768, 32767),
    activate=st.booleans(),
    action=st.booleans(),
    estop=st.booleans(),
    release=st.booleans(),
)

statuses = st.builds(GripperStatus, **STATUS_FIELDS, error_bit=st.booleans())


@given(st.integers(0, 15), st.integers(0, 63), st.booleans())
def test_identifier_round_trip(node: int, command: int, error: bool) -> None:
    arbitration_id = pack_id(node, command, error)
    assert arbitration_id <= 0x7FF
    assert unpack_id(arbitration_id) == (node, command, error)


def test_every_identifier_splits_and_packs_back() -> None:
    """unpack_id reads a precomputed table: all 2,048 standard identifiers checked, and -1 refused."""
    for arbitration_id in range(0x800):
        assert pack_id(*unpack_id(arbitration_id)) == arbitration_id
    with pytest.raises(ProtocolError):
        unpack_id(-1)


def test_identifier_layout() -> None:
    # docs/protocols.md §2: id = node << 7 | command << 1 | error
    assert pack_id(3, 61) == 0x1FA
    assert pack_id(15, 63, True) == 0x7FF
    assert unpack_id(0x079) == (0, 60, True)


@pytest.mark.parametrize(("node", "command"), [(16, 0), (-1, 0), (0, 64), (0, -1)])
def test_identifier_refuses_out_of_range(node: int, command: int) -> None:
    with pytest.raises(LimitError):
        pack_id(node, command)


def test_unpack_refuses_extended_identifier() -> None:
    with pytest.raises(ProtocolError):
        unpack_id(0x800)


@given(commands)
def test_command_round_trip(cmd: GripperCommand) -> None:
    data = encode_command(cmd)
    assert len(data) == 5
    assert decode_command(data) == cmd


@given(statuses)
def test_status_round_trip(status: GripperStatus) -> None:
    data = encode_status(status)
    assert len(data) == 4
    assert decode_status(data, status.error_bit) == status


def test_command_bytes_big_endian_and_msb_first_flags() -> None:
    cmd = GripperCommand(position=200, speed=100, current_ma=600, activate=True, action=True, estop=False)
    assert encode_command(cmd) == bytes([200, 100, 0x02, 0x58, 0xC0])
    assert encode_command(GripperCommand(0, 0, -2, False, False, True, True)) == bytes(
        [0, 0, 0xFF, 0xFE, 0x30]
    )


@pytest.mark.parametrize(
    ("flags", "detection"),
    [
        (0x00, Detection.MOVING),
        (0x20, Detection.CLOSING_OBJECT),
        (0x10, Detection.OPENING_OBJECT),
        (0x30, Detection.AT_POSITION),
    ],
)
def test_status_detection_bits(flags: int, detection: Detection) -> None:
    # docs/protocols.md §2: value bit 0 at 0x20, bit 1 at 0x10 (the vendor library reads them swapped)
    assert decode_status(bytes([0, 0, 0, flags])).detection is detection


def test_status_flag_bits() -> None:
    st_ = decode_status(bytes([255, 0xFE, 0x0C, 0x80 | 0x01]))
    assert (st_.position, st_.current_ma, st_.activated, st_.calibrated) == (255, -500, True, True)
    assert not (st_.action or st_.temperature_error or st_.timeout_error or st_.estop_error)
    assert decode_status(bytes([0, 0, 0, 0x40])).action
    assert decode_status(bytes([0, 0, 0, 0x08])).temperature_error
    assert decode_status(bytes([0, 0, 0, 0x04])).timeout_error
    assert decode_status(bytes([0, 0, 0, 0x02])).estop_error


@pytest.mark.parametrize("field", ["position", "speed"])
@pytest.mark.parametrize("value", [-1, 256])
def test_encode_command_refuses_out_of_range(field: str, value: int) -> None:
    kw = {"position": 0, "speed": 0, field: value}
    with pytest.raises(LimitError):
        encode_command(GripperCommand(current_ma=0, activate=True, action=True, estop=False, **kw))


def test_encode_status_refuses_out_of_range() -> None:
    with pytest.raises(LimitError):
        encode_status(GripperStatus(0, 40000, False, False, Detection.MOVING, False, False, False, False))


# every command id x every data length 0..8: the table either decodes it or says why it does not
@pytest.mark.parametrize("command", range(64))
def test_every_command_and_length(command: int) -> None:
    spec = COMMANDS.get(command)
    for length in range(9):
        data = bytes(range(1, length + 1))
        arbitration_id = pack_id(5, command)
        if spec is None:
            msg = decode_frame(arbitration_id, data)
            assert msg.value == data and msg.spec is None
            continue
        if length in spec.lengths:
            msg = decode_frame(arbitration_id, data)
            assert (msg.node, msg.command, msg.error, msg.remote) == (5, command, False, False)
            again = encode_frame(5, command, msg.value)  # reserved flag bits are not carried over
            assert (again.arbitration_id, len(again.data), again.remote) == (arbitration_id, length, False)
            assert decode_frame(again.arbitration_id, again.data).value == msg.value
        else:
            with pytest.raises(FrameLengthError) as info:
                decode_frame(arbitration_id, data)
            assert info.value.actual == length
            assert info.value.expected == spec.lengths
            assert spec.name in str(info.value)
            assert isinstance(info.value, ProtocolError)
        assert describe(arbitration_id, data)  # the monitor never raises


@pytest.mark.parametrize("command", [c for c, s in COMMANDS.items() if s.direction is Direction.REMOTE])
def test_remote_requests(command: int) -> None:
    frame = encode_frame(2, command, remote=True)
    assert frame == CanFrame(pack_id(2, command), b"", True)
    msg = decode_frame(frame.arbitration_id, b"", True)
    assert msg.remote and msg.value is None and not msg.from_node


@pytest.mark.parametrize("command", [c for c, s in COMMANDS.items() if s.direction is not Direction.REMOTE])
def test_remote_frame_for_data_command_is_refused(command: int) -> None:
    with pytest.raises(ProtocolError):
        decode_frame(pack_id(0, command), b"", True)


def test_reply_values() -> None:
    assert decode_frame(pack_id(1, Cmd.TEMPERATURE), b"\xff\xfb").value == -5
    assert decode_frame(pack_id(1, Cmd.BUS_VOLTAGE), b"\x5d\xc0").value == 24000
    assert decode_frame(pack_id(1, Cmd.IQ), b"\xfe\x0c").value == -500
    info = decode_frame(pack_id(1, Cmd.DEVICE_INFO), bytes([2, 23, 9, 0xFF, 0xFF, 0xFF, 0xFE])).value
    assert info == DeviceInfo(hardware_version=2, batch_date=23, software_version=9, serial=-2)
    enc = decode_frame(pack_id(1, Cmd.ENCODER), bytes([0, 0, 1, 0, 0xFF, 0xFF, 0xFF, 0xFF])).value
    assert enc == EncoderData(256, -1)
    assert decode_frame(pack_id(1, Cmd.PING), b"").from_node


@given(st.lists(st.booleans(), min_size=11, max_size=11))
def test_error_state_round_trip(bits: list[bool]) -> None:
    es = ErrorState(*bits)
    frame = encode_frame(0, Cmd.ERROR_STATE, es)
    assert decode_frame(frame.arbitration_id, frame.data).value == es


def test_error_state_bit_order() -> None:
    # docs/protocols.md §2: byte 0 = error, temperature, encoder, vbus, driver, velocity, current, estop
    es = decode_frame(pack_id(0, Cmd.ERROR_STATE), bytes([0x81, 0xA0])).value
    assert es.error and es.estop and es.calibrated and es.watchdog
    assert not (es.temperature or es.activated or es.current)
    assert es.active() == ["estop", "watchdog"]


@given(st.integers(0, 2**32 - 1), st.sampled_from(WatchdogAction))
def test_watchdog_and_heartbeat_round_trip(ms: int, action: WatchdogAction) -> None:
    frame = encode_frame(4, Cmd.WATCHDOG, Watchdog(ms, action))
    assert frame.data == ms.to_bytes(4, "big") + bytes([action])
    assert decode_frame(frame.arbitration_id, frame.data).value == Watchdog(ms, action)
    hb = encode_frame(4, Cmd.HEARTBEAT_SETUP, ms)
    assert decode_frame(hb.arbitration_id, hb.data).value == ms


def test_set_can_id_and_empty_commands() -> None:
    assert encode_frame(0, Cmd.SET_CAN_ID, 7).data == b"\x07"
    for cmd in (
        Cmd.ESTOP,
        Cmd.CLEAR_ERROR,
        Cmd.IDLE,
        Cmd.SAVE_CONFIG,
        Cmd.RESET,
        Cmd.GRIPPER_CALIBRATE,
        Cmd.HEARTBEAT,
    ):
        assert encode_frame(0, cmd).data == b""
    assert encode_frame(0, Cmd.GRIPPER_COMMAND).data == b""  # the poll


def test_error_bit_reaches_decoded_status() -> None:
    msg = decode_frame(pack_id(0, Cmd.GRIPPER_STATUS, True), bytes([1, 0, 0, 0]))
    assert msg.error and msg.value.error_bit
    assert not decode_frame(pack_id(0, Cmd.GRIPPER_STATUS), bytes([1, 0, 0, 0])).value.error_bit


@given(st.integers(0, 0x7FF), st.binary(max_size=8), st.booleans())
def test_describe_never_raises(arbitration_id: int, data: bytes, remote: bool) -> None:
    assert isinstance(describe(arbitration_id, data, remote), str)


def test_describe_names_fields() -> None:
    text = describe(pack_id(2, 60, True), bytes([10, 0xFE, 0x0C, 0xF1]))
    assert "node 2" in text and "gripper_status" in text and "AT_POSITION" in text and "ERR" in text
    assert "poll" in describe(pack_id(0, 61), b"")
    assert "BAD LENGTH" in describe(pack_id(0, 60), b"\x01")
