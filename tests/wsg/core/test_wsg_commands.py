"""Every command of both manuals: request and reply layouts, errata, typed values
(grippers.drivers.wsg.commands)."""

from __future__ import annotations

import struct

import pytest

from grippers.drivers.errors import LimitError, ProtocolError
from grippers.drivers.wsg.commands import (
    AUTO_UPDATE_COMMANDS,
    COMMANDS,
    Cmd,
    DeviceType,
    FingerFlags,
    FingerInfo,
    FingerType,
    FirmwareVersion,
    GraspingState,
    GraspingStatistics,
    RequestFormatError,
    SoftLimits,
    SystemFlags,
    SystemInfo,
    SystemLimits,
    command_name,
    decode_reply,
    decode_request,
    describe,
    encode_reply,
    encode_request,
)
from grippers.drivers.wsg.protocol import Packet, Status, decode_packet


def f32(*values: float) -> bytes:
    return struct.pack(f"<{len(values)}f", *values)


# (command, request fields, request bytes, reply fields, reply data bytes); data in little-endian per
# WSG manual 4.0.x §1, floats IEEE 754 single precision.
CASES = [
    (Cmd.LOOP, {"data": b"\x01\x02\xaa"}, b"\x01\x02\xaa", {"data": b"\x01\x02\xaa"}, b"\x01\x02\xaa"),
    (Cmd.DISCONNECT, {}, b"", {}, b""),
    (Cmd.HOMING, {"direction": 2}, b"\x02", {}, b""),
    (
        Cmd.PREPOSITION,
        {"relative": True, "stop_on_block": False, "width": 50.0, "speed": 100.0},
        b"\x01" + f32(50.0, 100.0),
        {},
        b"",
    ),
    (
        Cmd.PREPOSITION,
        {"relative": False, "stop_on_block": True, "width": 10.5, "speed": 5.0},
        b"\x02" + f32(10.5, 5.0),
        {},
        b"",
    ),
    (Cmd.STOP, {}, b"", {}, b""),
    (Cmd.FAST_STOP, {}, b"", {}, b""),
    (Cmd.ACK_FAST_STOP, {"key": b"ack"}, b"\x61\x63\x6b", {}, b""),
    (Cmd.GRIP, {"width": 20.0, "speed": 50.0}, f32(20.0, 50.0), {}, b""),
    (Cmd.RELEASE, {"width": 40.0, "speed": 60.0}, f32(40.0, 60.0), {}, b""),
    (Cmd.SET_ACCELERATION, {"acceleration": 150.0}, b"\x00\x00\x16\x43", {}, b""),
    (Cmd.GET_ACCELERATION, {}, b"", {"acceleration": 150.0}, b"\x00\x00\x16\x43"),
    (Cmd.SET_FORCE_LIMIT, {"force": 40.0}, f32(40.0), {}, b""),
    (Cmd.GET_FORCE_LIMIT, {}, b"", {"force": 40.0}, f32(40.0)),
    (Cmd.SET_SOFT_LIMITS, {"minus": 5.0, "plus": 100.0}, f32(5.0, 100.0), {}, b""),
    (Cmd.GET_SOFT_LIMITS, {}, b"", {"minus": 5.0, "plus": 100.0}, f32(5.0, 100.0)),
    (Cmd.CLEAR_SOFT_LIMITS, {}, b"", {}, b""),
    (Cmd.OVERDRIVE, {"enable": True}, b"\x01", {}, b""),
    (Cmd.TARE, {}, b"", {}, b""),
    (
        Cmd.GET_SYSTEM_STATE,
        {"auto_update": True, "changes_only": True, "period_ms": 100},
        b"\x03\x64\x00",
        {"state": SystemFlags.SF_REFERENCED | SystemFlags.SF_FAST_STOP},
        b"\x01\x10\x00\x00",
    ),
    (
        Cmd.GET_GRASPING_STATE,
        {"auto_update": True, "changes_only": False, "period_ms": 10},
        b"\x01\x0a\x00",
        {"state": GraspingState.HOLDING},
        b"\x04",
    ),
    (
        Cmd.GET_GRASPING_STATISTICS,
        {"reset": True},
        b"\x01",
        {"total": 70000, "no_part": 3, "lost_part": 2},
        b"\x70\x11\x01\x00\x03\x00\x02\x00",
    ),
    (
        Cmd.GET_WIDTH,
        {"auto_update": False, "changes_only": False, "period_ms": 0},
        b"\x00\x00\x00",
        {"width": 50.0},
        f32(50.0),
    ),
    (
        Cmd.GET_SPEED,
        {"auto_update": True, "changes_only": True, "period_ms": 0x1234},
        b"\x03\x34\x12",
        {"speed": -20.0},
        f32(-20.0),
    ),
    (
        Cmd.GET_FORCE,
        {"auto_update": False, "changes_only": True, "period_ms": 10},
        b"\x02\x0a\x00",
        {"force": 12.5},
        f32(12.5),
    ),
    (Cmd.GET_TEMPERATURE, {}, b"", {"temperature": -1.0}, b"\xf6\xff"),
    (
        Cmd.GET_SYSTEM_INFO,
        {},
        b"",
        {
            "device_type": DeviceType.WSG50,
            "hw_revision": 3,
            "firmware": FirmwareVersion(4, 0, 1),
            "serial": 4711,
        },
        b"\x01\x03\x10\x40\x67\x12\x00\x00",
    ),
    (Cmd.SET_DEVICE_TAG, {"tag": "cell 3"}, b"cell 3", {}, b""),
    (Cmd.GET_DEVICE_TAG, {}, b"", {"tag": "cell 3"}, b"cell 3"),
    (
        Cmd.GET_SYSTEM_LIMITS,
        {},
        b"",
        {
            "stroke": 110.0,
            "min_speed": 5.0,
            "max_speed": 420.0,
            "min_acceleration": 100.0,
            "max_acceleration": 5000.0,
            "min_force": 5.0,
            "nominal_force": 80.0,
            "overdrive_force": 120.0,
        },
        f32(110.0, 5.0, 420.0, 100.0, 5000.0, 5.0, 80.0, 120.0),
    ),
    (Cmd.GET_FINGER1_INFO, {}, b"", {"finger_type": FingerType.WSG_FMF, "data_size": 4}, b"\x01\x04\x00"),
    (Cmd.GET_FINGER1_FLAGS, {}, b"", {"flags": FingerFlags.POWER_ON | FingerFlags.POWER_FAULT}, b"\x01\x01"),
    (Cmd.FINGER1_POWER, {"power": True}, b"\x01", {}, b""),
    (Cmd.GET_FINGER1_DATA, {}, b"", {"data": b"\x00\x00\x20\x41"}, b"\x00\x00\x20\x41"),
    (Cmd.GET_FINGER2_INFO, {}, b"", {"finger_type": FingerType.GENERIC, "data_size": 0}, b"\x00\x00\x00"),
    (Cmd.GET_FINGER2_FLAGS, {}, b"", {"flags": FingerFlags.COMM_OPEN}, b"\x04\x00"),
    (Cmd.FINGER2_POWER, {"power": False}, b"\x00", {}, b""),
    (Cmd.GET_FINGER2_DATA, {}, b"", {"data": b""}, b""),
]


def test_the_table_covers_every_command_of_both_manuals() -> None:
    ids = {
        0x06,
        0x07,
        *range(0x20, 0x27),
        *range(0x30, 0x39),
        *range(0x40, 0x47),
        *range(0x50, 0x54),
        *range(0x60, 0x64),
        *range(0x70, 0x74),
    }
    assert set(COMMANDS) == ids == {int(c) for c in Cmd}
    assert {int(c[0]) for c in CASES} == ids
    assert set(AUTO_UPDATE_COMMANDS) == {0x40, 0x41, 0x43, 0x44, 0x45}  # docs/protocols.md §1
    assert {s.id for s in COMMANDS.values() if s.is_async} == {0x20, 0x21, 0x25, 0x26, 0x62, 0x72}
    # Firmware 2.2.0 lacks 46h and 60h-73h (docs/protocols.md §1).
    assert {s.id for s in COMMANDS.values() if s.min_firmware_major > 2} == {
        0x46,
        *range(0x60, 0x64),
        *range(0x70, 0x74),
    }


@pytest.mark.parametrize(
    ("cmd", "req", "req_bytes", "rep", "rep_bytes"),
    CASES,
    ids=[f"{c[0].name}-{i}" for i, c in enumerate(CASES)],
)
def test_request_and_reply_layouts(cmd, req, req_bytes, rep, rep_bytes) -> None:
    assert encode_request(cmd, **req) == req_bytes
    assert decode_request(cmd, req_bytes) == req
    payload = encode_reply(cmd, Status.E_SUCCESS, **rep)
    assert payload == b"\x00\x00" + rep_bytes
    reply = decode_reply(cmd, payload)
    assert reply.ok and reply.status is Status.E_SUCCESS
    assert reply.fields == rep
    for name, value in rep.items():
        assert type(reply.fields[name]) is type(value), name
    # An error reply carries no data (WSG manual 4.0.x §1.2.2) and decodes for every command.
    error = decode_reply(cmd, encode_reply(cmd, Status.E_ACCESS_DENIED, **rep))
    assert error.status is Status.E_ACCESS_DENIED and error.fields == {} and error.value is None
    assert encode_reply(cmd, Status.E_CMD_PENDING) == b"\x1a\x00"
    # The monitor's one-liner names the command and never raises.
    assert COMMANDS[cmd].name in describe(Packet(cmd, req_bytes), "request")
    assert COMMANDS[cmd].name in describe(Packet(cmd, payload), "reply")


def test_errata_of_the_notes_are_applied() -> None:
    # 42h is Get Gripping Statistics (both manuals print "Command ID: 40h").
    assert COMMANDS[0x42].name == "GET_GRASPING_STATISTICS"
    # 21h flags: D0 relative, D1 stop on block.
    assert encode_request(Cmd.PREPOSITION, relative=True, width=1, speed=1)[0] == 0x01
    assert encode_request(Cmd.PREPOSITION, stop_on_block=True, width=1, speed=1)[0] == 0x02
    # 24h key is "ack"; it is the default.
    assert encode_request(Cmd.ACK_FAST_STOP) == b"ack"
    # 43h-45h replies are float32 (4 bytes), not "Byte 0".
    with pytest.raises(ProtocolError):
        decode_reply(Cmd.GET_WIDTH, b"\x00\x00\x01")
    # 60h SIZE is bytes 1..2.
    assert decode_reply(0x60, b"\x00\x00\x02\x10\x00").fields == {
        "finger_type": FingerType.WSG_DSA,
        "data_size": 16,
    }
    # 62h power is byte 0 (one parameter byte).
    assert encode_request(0x62, power=True) == b"\x01"
    # 46h: i16 in 0.1 degC. Both 4.0.x manuals print "FFF5h = -1.0 °C"; as i16 tenths FFF5h is -1.1 °C and
    # -1.0 °C is FFF6h (the other examples, FFFFh = -0.1 °C and 000Ah = 1.0 °C, agree with that).
    for raw, celsius in (
        (0xFFF6, -1.0),
        (0xFFF5, -1.1),
        (0xFFFF, -0.1),
        (0, 0.0),
        (0x0A, 1.0),
        (0xC8, 20.0),
        (0x1F4, 50.0),
    ):
        assert decode_reply(0x46, b"\x00\x00" + raw.to_bytes(2, "little")).value == pytest.approx(celsius)
        assert encode_reply(0x46, 0, temperature=celsius)[2:] == raw.to_bytes(2, "little")


def test_auto_update_request_defaults_to_a_single_query() -> None:
    for cmd in AUTO_UPDATE_COMMANDS:
        assert encode_request(cmd) == b"\x00\x00\x00"
        assert decode_request(cmd, b"\x01\x0a\x00") == {
            "auto_update": True,
            "changes_only": False,
            "period_ms": 10,
        }


def test_firmware_version_nibbles_and_text() -> None:
    v = FirmwareVersion.from_word(0x4010)
    assert (v.major, v.minor1, v.minor2, v.rc) == (4, 0, 1, 0)
    assert str(v) == "4.0.1"
    assert str(FirmwareVersion.from_word(0x2203)) == "2.2.0-rc3"
    assert FirmwareVersion.parse("2.2.0-rc3").to_word() == 0x2203
    assert FirmwareVersion.coerce("4.0.1") == FirmwareVersion.coerce(0x4010) == v
    assert FirmwareVersion(2, 2, 0) < FirmwareVersion(4, 0, 1)
    with pytest.raises(LimitError):
        FirmwareVersion.parse("four")
    with pytest.raises(LimitError):
        FirmwareVersion(16, 0, 0)
    info = decode_reply(
        0x50, encode_reply(0x50, 0, device_type=6, hw_revision=1, firmware="2.2.0", serial=1)
    ).value
    assert info == SystemInfo(DeviceType.WSG70, 1, FirmwareVersion(2, 2, 0), 1)


def test_typed_values() -> None:
    assert SystemFlags.SF_FAST_STOP == 1 << 12 and SystemFlags.SF_SCRIPT_FAILURE == 1 << 20  # Appendix B
    assert SystemFlags.SF_MOVING == 2 and SystemFlags.SF_TARGET_POS_REACHED == 0x80
    assert [s.value for s in GraspingState] == list(range(8))
    assert GraspingState.GRIPPING is GraspingState.GRASPING
    # Unknown values decode to plain ints, never crash.
    assert decode_reply(0x41, b"\x00\x00\x09").value == 9
    assert decode_reply(0x50, b"\x00\x00\x09\x00\x10\x40\x00\x00\x00\x00").value.device_type == 9
    state = decode_reply(0x40, b"\x00\x00\x00\x00\x00\x80").value
    assert isinstance(state, SystemFlags) and int(state) == 1 << 31
    assert decode_reply(
        0x42, encode_reply(0x42, 0, total=1, no_part=2, lost_part=3)
    ).value == GraspingStatistics(1, 2, 3)
    assert decode_reply(0x35, encode_reply(0x35, 0, minus=1, plus=2)).value == SoftLimits(1.0, 2.0)
    assert decode_reply(0x70, encode_reply(0x70, 0, finger_type=0, data_size=0)).value == FingerInfo(
        FingerType.GENERIC, 0
    )
    limits = decode_reply(0x53, b"\x00\x00" + f32(*range(8))).value
    assert isinstance(limits, SystemLimits) and limits.overdrive_force == 7.0
    # Unknown status codes and unknown commands still decode.
    unknown = decode_reply(0x90, b"\x0e\x00")
    assert unknown.status is Status.E_CMD_UNKNOWN and unknown.status_name == "E_CMD_UNKNOWN"
    assert decode_reply(0x43, b"\x63\x00").status == 99
    assert decode_reply(0x99, b"\x00\x00\x01\x02").fields == {"data": b"\x01\x02"}


def test_device_tag_decodes_any_byte_and_strips_nul() -> None:
    assert decode_reply(0x52, b"\x00\x00abc\x00\x00").value == "abc"  # 2.2.0 §3.5.2: terminating NULs
    assert decode_request(0x51, b"a\x07b") == {"tag": "a\x07b"}  # control characters reach the simulator
    with pytest.raises(LimitError):
        encode_request(0x51, tag="caf\u00e9")


@pytest.mark.parametrize(
    ("cmd", "payload", "status"),
    [
        (0x22, b"\x00", Status.E_NO_PARAM_EXPECTED),
        (0x50, b"\x00", Status.E_NO_PARAM_EXPECTED),
        (0x07, b"\x01", Status.E_NO_PARAM_EXPECTED),
        (0x21, b"\x00" * 8, Status.E_CMD_FORMAT_ERROR),
        (0x21, b"\x00" * 10, Status.E_CMD_FORMAT_ERROR),
        (0x20, b"", Status.E_CMD_FORMAT_ERROR),
        (0x24, b"ac", Status.E_CMD_FORMAT_ERROR),
        (0x43, b"\x01", Status.E_CMD_FORMAT_ERROR),
        (0x06, bytes(257), Status.E_CMD_FORMAT_ERROR),  # 4.0.x §3.1.1: at most 256 bytes
        (0x90, b"", Status.E_CMD_UNKNOWN),
    ],
)
def test_request_length_errors_carry_the_devices_answer(cmd, payload, status) -> None:
    with pytest.raises(RequestFormatError) as info:
        decode_request(cmd, payload)
    assert info.value.status is status
    assert isinstance(info.value, ProtocolError)
    assert command_name(cmd).split()[0] in str(info.value) or cmd == 0x90


def test_reply_length_errors() -> None:
    with pytest.raises(ProtocolError):
        decode_reply(0x53, b"\x00\x00" + bytes(31))  # truncated
    with pytest.raises(ProtocolError):
        decode_reply(0x43, b"\x00\x00" + bytes(5))  # oversized
    with pytest.raises(ProtocolError):
        decode_reply(0x43, b"\x00")  # no status


def test_encode_request_refuses_bad_fields() -> None:
    with pytest.raises(ProtocolError):
        encode_request(0x21, width=1.0)  # speed missing
    with pytest.raises(ProtocolError):
        encode_request(0x25, width=1.0, speed=1.0, force=3.0)  # unknown field
    with pytest.raises(LimitError):
        encode_request(0x43, period_ms=70000)
    with pytest.raises(LimitError):
        encode_request(0x25, width=1e39, speed=1.0)
    with pytest.raises(ProtocolError):
        encode_request(0x91)


def test_manual_example_reply_under_30h() -> None:
    # The 4.0.x manual's §1.2.2 example 3 shows "Read acceleration" data under id 30h (Set Acceleration);
    # the data belongs to 31h (Get Acceleration). Both readings of the packet are pinned here.
    packet = decode_packet(bytes.fromhex("AAAAAA300600000000001643DCCB"))
    assert decode_reply(Cmd.GET_ACCELERATION, packet.payload).value == 150.0
    with pytest.raises(ProtocolError):
        decode_reply(Cmd.SET_ACCELERATION, packet.payload)
    assert "[" in describe(packet, "reply")  # shown with the reason, not raised


def test_describe_lines() -> None:
    req = Packet(0x21, encode_request(0x21, stop_on_block=True, width=50, speed=100))
    assert describe(req, "request") == (
        "-> PREPOSITION (21h) relative=False stop_on_block=True width=50 speed=100"
    )
    reply = Packet(0x40, encode_reply(0x40, 0, state=SystemFlags.SF_REFERENCED | SystemFlags.SF_MOVING))
    assert describe(reply, "reply") == "<- GET_SYSTEM_STATE (40h) E_SUCCESS state=SF_REFERENCED|SF_MOVING"
    assert describe(Packet(0x21, b"\x1a\x00"), "reply") == "<- PREPOSITION (21h) E_CMD_PENDING"
    assert describe(Packet(0x90, b"\x0e\x00"), "reply") == "<- command 90h E_CMD_UNKNOWN"
    assert "no status" in describe(Packet(0x43, b""), "reply")
