"""The Modbus RTU codec and the register map against the manuals' example frames (docs/protocols-robotiq.md
§1-2, each CRC checked there) and against pymodbus's own CRC as an independent peer."""

from __future__ import annotations

import pytest
from hypothesis import given
from hypothesis import strategies as st
from pymodbus.framer import FramerRTU

from grippers.drivers.robotiq import modbus
from grippers.drivers.robotiq.modbus import RequestParser, ResponseParser
from grippers.drivers.robotiq.registers import (
    COMMAND_ADDRESS,
    STATUS_ADDRESS,
    ActivationState,
    Command,
    ObjectDetection,
    Status,
)

H = bytes.fromhex

# The 2F-85/2F-140 and Hand-E manuals' Modbus RTU examples (slave 9).
ACTIVATION_CLEAR = H("09 10 03 E8 00 03 06 00 00 00 00 00 00 73 30")
ACTIVATION_SET = H("09 10 03 E8 00 03 06 01 00 00 00 00 00 72 E1")
CLOSE_FULL = H("09 10 03 E8 00 03 06 09 00 00 FF FF FF 42 29")
OPEN_FULL = H("09 10 03 E8 00 03 06 09 00 00 00 FF FF 72 19")
WRITE_ECHO = H("09 10 03 E8 00 03 01 30")
READ1_03 = H("09 03 07 D0 00 01 85 CF")
READ3_03 = H("09 03 07 D0 00 03 04 0E")
READ1_04 = H("09 04 07 D0 00 01 30 0F")
READ3_04 = H("09 04 07 D0 00 03 B1 CE")
ACTIVATING_04 = H("09 04 02 11 00 54 A1")
ACTIVATED_04 = H("09 04 02 31 00 4D 61")
ACTIVATING_03 = H("09 03 02 11 00 55 D5")
ACTIVATED_03 = H("09 03 02 31 00 4C 15")
GRIPPING_03 = H("09 03 06 39 00 00 FF 0E 0A F7 8B")
OPENING_04 = H("09 04 06 39 00 00 00 BB 10 71 06")
OPENED_04 = H("09 04 06 F9 00 00 00 0D 00 17 AA")
GRASPED_04 = H("09 04 06 B9 00 00 FF BD 00 5C 9A")
RW_REPLY = H("09 17 04 01 00 09 E6 F6 C1")

ALL = [
    ACTIVATION_CLEAR, ACTIVATION_SET, CLOSE_FULL, OPEN_FULL, WRITE_ECHO, READ1_03, READ3_03, READ1_04,
    READ3_04, ACTIVATING_04, ACTIVATED_04, ACTIVATING_03, ACTIVATED_03, GRIPPING_03, OPENING_04, OPENED_04,
    GRASPED_04, RW_REPLY,
]  # fmt: skip


@pytest.mark.parametrize("frame", ALL, ids=lambda f: f.hex(" "))
def test_every_manual_example_carries_our_crc_and_pymodbus_s(frame: bytes) -> None:
    assert modbus.crc16(frame[:-2]) == int.from_bytes(frame[-2:], "little")
    assert FramerRTU.check_CRC(frame[:-2], int.from_bytes(frame[-2:], "big"))


def test_requests_are_built_byte_for_byte_as_the_manual_shows() -> None:
    assert modbus.write_request(9, COMMAND_ADDRESS, Command().registers()) == ACTIVATION_CLEAR
    assert modbus.write_request(9, COMMAND_ADDRESS, Command(act=True).registers()) == ACTIVATION_SET
    close = Command(act=True, gto=True, position=255, speed=255, force=255)
    assert modbus.write_request(9, COMMAND_ADDRESS, close.registers()) == CLOSE_FULL
    opening = Command(act=True, gto=True, position=0, speed=255, force=255)
    assert modbus.write_request(9, COMMAND_ADDRESS, opening.registers()) == OPEN_FULL
    assert modbus.read_request(9, STATUS_ADDRESS, 1) == READ1_03
    assert modbus.read_request(9, STATUS_ADDRESS, 3) == READ3_03
    assert modbus.read_request(9, STATUS_ADDRESS, 1, modbus.READ_INPUT) == READ1_04
    assert modbus.read_request(9, STATUS_ADDRESS, 3, modbus.READ_INPUT) == READ3_04
    assert modbus.write_response(9, COMMAND_ADDRESS, 3) == WRITE_ECHO


def _decode(frame: bytes, function: int, count: int) -> modbus.Response:
    p = ResponseParser(9)
    p.expect(function, count)
    (reply,) = p.feed(frame)
    return reply


def test_status_replies_decode_as_the_manual_reads_them() -> None:
    s = Status.from_registers(_decode(ACTIVATING_04, 4, 1).values)
    assert s.act and s.sta == ActivationState.IN_PROGRESS and not s.activated
    s = Status.from_registers(_decode(ACTIVATED_03, 3, 1).values)
    assert s.activated
    s = Status.from_registers(_decode(OPENING_04, 4, 3).values)
    assert s.gto and s.obj == ObjectDetection.MOVING and s.position == 0xBB and s.current_ma == 160
    s = Status.from_registers(_decode(OPENED_04, 4, 3).values)
    assert s.obj == ObjectDetection.AT_POSITION and s.position == 13 and s.position_echo == 0
    s = Status.from_registers(_decode(GRASPED_04, 4, 3).values)
    assert s.obj == ObjectDetection.CONTACT_CLOSING and s.position_echo == 0xFF and s.position == 0xBD
    s = Status.from_registers(_decode(GRIPPING_03, 3, 3).values)
    assert s.moving and s.position == 0x0E and s.current == 0x0A
    assert _decode(RW_REPLY, 0x17, 2).values == (0x0100, 0x09E6)
    assert Status.from_registers(Status.from_registers((0xB900, 0x00FF, 0xBD00)).registers()).position == 0xBD


def test_requests_parse_on_the_device_side() -> None:
    p = RequestParser(9)
    reqs = p.feed(CLOSE_FULL + READ3_03 + READ1_04)
    assert [r.function for r in reqs] == [0x10, 0x03, 0x04]
    assert Command.from_registers(reqs[0].values) == Command(
        act=True, gto=True, position=255, speed=255, force=255
    )
    assert (reqs[1].address, reqs[1].count) == (STATUS_ADDRESS, 3)
    rw = modbus.read_write_request(9, STATUS_ADDRESS, 3, COMMAND_ADDRESS, Command(act=True).registers())
    (r,) = p.feed(rw)
    assert (r.function, r.address, r.count, r.write_address, r.values) == (
        0x17,
        STATUS_ADDRESS,
        3,
        COMMAND_ADDRESS,
        (0x0100, 0, 0),
    )


def test_parser_is_silent_on_another_slave_and_a_bad_crc_and_resynchronises_on_garbage() -> None:
    p = RequestParser(9)
    other = modbus.read_request(10, STATUS_ADDRESS, 3)
    bad = READ3_03[:-1] + bytes([READ3_03[-1] ^ 0xFF])
    assert p.feed(other) == [] and p.other_slaves == 1
    assert p.feed(bad) == []
    assert p.feed(b"\x00\xff\x09\x10\x77" + READ3_03)[0].raw == READ3_03  # garbage, even a false header
    q = ResponseParser(9)
    q.expect(3, 3)
    assert q.feed(b"\x09\x03\x06\x01" + GRIPPING_03)[0].raw == GRIPPING_03


def test_frames_fed_byte_by_byte_come_out_whole() -> None:
    p = ResponseParser(9)
    p.expect(0x10, 3)
    out = [r for b in WRITE_ECHO for r in p.feed(bytes([b]))]
    assert len(out) == 1 and (out[0].address, out[0].count) == (COMMAND_ADDRESS, 3)


def test_exception_responses_round_trip() -> None:
    frame = modbus.exception_response(9, 0x03, modbus.ExceptionCode.ILLEGAL_DATA_ADDRESS)
    assert frame[:3] == H("09 83 02")
    p = ResponseParser(9)
    p.expect(3, 3)
    (r,) = p.feed(frame)
    assert r.function == 3 and r.exception == 2


@given(
    regs=st.lists(st.integers(0, 0xFFFF), min_size=1, max_size=20),
    garbage=st.binary(max_size=12),
    slave=st.integers(1, 247),
)
def test_any_registers_survive_garbage_before_them(regs: list[int], garbage: bytes, slave: int) -> None:
    p = ResponseParser(slave)
    p.expect(3, len(regs))
    frame = modbus.read_response(slave, 3, regs)
    out = p.feed(garbage + frame)
    assert [r.values for r in out][-1:] == [tuple(regs)]


def test_builders_refuse_what_no_frame_holds() -> None:
    with pytest.raises(ValueError):
        modbus.read_request(9, STATUS_ADDRESS, 0)
    with pytest.raises(ValueError):
        modbus.write_request(300, COMMAND_ADDRESS, [1])
    with pytest.raises(ValueError):
        Command(position=256)


def test_frames_are_dissected_for_the_monitor_and_the_wire_log() -> None:
    from grippers.drivers.dissect import FROM_GRIPPER, TO_GRIPPER, render_line
    from grippers.drivers.robotiq.dissect import ModbusStream

    (req,) = ModbusStream(TO_GRIPPER).feed(CLOSE_FULL)
    assert "rACT|rGTO rPR=255 rSP=255 rFR=255" in render_line(req) and req["node"] == 9
    replies = ModbusStream(FROM_GRIPPER)
    assert replies.feed(GRASPED_04[:5]) == []
    (rep,) = replies.feed(GRASPED_04[5:])
    assert rep["fields"]["gOBJ"] == "CONTACT_CLOSING" and rep["fields"]["gPO"] == 0xBD


def test_the_client_logs_each_frame_decoded(caplog: pytest.LogCaptureFixture) -> None:
    import logging

    from grippers.drivers.robotiq.client import RobotiqClient
    from grippers.drivers.robotiq.sim import RobotiqModel, serve

    server = serve(RobotiqModel())
    try:
        client = RobotiqClient.tcp("127.0.0.1", server.port, timeout=2)
        with caplog.at_level(logging.DEBUG, logger="grippers.wire"):
            client.read_status()
        client.close()
    finally:
        server.close()
    lines = [r.getMessage() for r in caplog.records if r.name == "grippers.wire"]
    assert any("read holding registers 0x07D0 x3" in ln for ln in lines)
    assert any("gSTA=RESET" in ln for ln in lines)
