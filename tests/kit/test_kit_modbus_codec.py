"""The kit's Modbus codec alone: RTU and MBAP framing round trips, and every bad input a typed error
(hypothesis feeds arbitrary bytes, cut anywhere). pymodbus's CRC is the independent check of ours."""

from __future__ import annotations

import socket

import pytest
from hypothesis import given
from hypothesis import strategies as st
from pymodbus.framer import FramerRTU

from grippers import CommandFailed, GripperError, LimitError, ProtocolError
from grippers.drivers import modbus
from grippers.drivers.modbus_model import RegisterMap
from grippers.drivers.modbus_tcp import MbapRequestParser, MbapResponseParser, mbap_frame
from grippers.kit import (
    ExceptionCode,
    IllegalDataAddress,
    ModbusClient,
    ModbusCRCError,
    ModbusException,
    ModbusFrameError,
    ModbusLengthError,
    ModbusUnitError,
    modbus_exception,
)

REGS = st.lists(st.integers(0, 0xFFFF), min_size=1, max_size=modbus.MAX_WRITE)
SLAVE = st.integers(1, 247)


def _chunks(data: bytes, cuts: list[int]) -> list[bytes]:
    points = sorted({c % (len(data) + 1) for c in cuts} | {0, len(data)})
    return [data[a:b] for a, b in zip(points, points[1:], strict=False)]


@given(data=st.binary(max_size=64))
def test_our_crc_is_pymodbus_s(data: bytes) -> None:
    assert FramerRTU.check_CRC(data, int.from_bytes(modbus.crc16(data).to_bytes(2, "little"), "big"))


@given(frame=st.binary(max_size=300), slave=st.none() | SLAVE)
def test_any_bytes_are_a_reply_or_a_typed_frame_error(frame: bytes, slave: int | None) -> None:
    try:
        reply = modbus.decode_rtu(frame, slave=slave)
    except ModbusFrameError as exc:
        assert isinstance(exc, ProtocolError | GripperError)
    else:
        assert reply.raw == frame and (slave is None or reply.slave == slave)


@given(
    regs=st.lists(st.integers(0, 0xFFFF), min_size=1, max_size=modbus.MAX_READ),
    at=st.integers(0),
    bit=st.integers(0, 7),
)
def test_one_flipped_bit_is_a_crc_or_length_error_never_a_wrong_value(
    regs: list[int], at: int, bit: int
) -> None:
    frame = bytearray(modbus.read_response(9, 3, regs))
    frame[at % len(frame)] ^= 1 << bit
    with pytest.raises((ModbusCRCError, ModbusLengthError, ModbusUnitError)):
        modbus.decode_rtu(bytes(frame), slave=9, function=3, count=len(regs))


def test_each_typed_error_of_a_whole_frame() -> None:
    good = modbus.read_response(9, 3, [1, 2])
    assert modbus.decode_rtu(good, slave=9, function=3, count=2).values == (1, 2)
    with pytest.raises(ModbusCRCError):
        modbus.decode_rtu(good[:-1] + bytes([good[-1] ^ 1]))
    with pytest.raises(ModbusLengthError):
        modbus.decode_rtu(good, function=3, count=3)  # two registers where three were asked
    with pytest.raises(ModbusLengthError):
        modbus.decode_rtu(good[:-1])
    with pytest.raises(ModbusUnitError) as caught:
        modbus.decode_rtu(good, slave=8)
    assert caught.value.unit == 9
    refused = modbus.decode_rtu(modbus.exception_response(9, 3, 2), slave=9, function=3)
    assert refused.exception == 2 and refused.function == 3


@given(data=st.binary(max_size=200), cuts=st.lists(st.integers(0), max_size=6), slave=st.none() | SLAVE)
def test_the_rtu_parsers_take_any_bytes_in_any_pieces(
    data: bytes, cuts: list[int], slave: int | None
) -> None:
    requests, responses = modbus.RequestParser(slave), modbus.ResponseParser(slave)
    responses.expect(3, 2)
    for piece in _chunks(data, cuts):
        for req in requests.feed(piece):
            assert slave is None or req.slave == slave
        for rep in responses.feed(piece):
            assert rep.function == 3 and (rep.exception is not None or len(rep.values) == 2)


@given(
    regs=REGS,
    slave=SLAVE,
    tid=st.integers(0, 0xFFFF),
    garbage=st.binary(max_size=12),
    cuts=st.lists(st.integers(0), max_size=4),
)
def test_rtu_requests_survive_garbage_and_mbap_requests_round_trip(
    regs: list[int], slave: int, tid: int, garbage: bytes, cuts: list[int]
) -> None:
    rtu = modbus.write_request(slave, 0x100, regs)
    parser = modbus.RequestParser(slave)
    found = [r for piece in _chunks(garbage + rtu, cuts) for r in parser.feed(piece)]
    assert found[-1].values == tuple(regs)
    mbap = MbapRequestParser()
    adu = mbap_frame(tid, slave, modbus.write_pdu(0x100, regs))
    (req,) = [r for piece in _chunks(adu, cuts) for r in mbap.feed(piece)]
    assert (req.transaction, req.slave, req.write_address, req.values) == (tid, slave, 0x100, tuple(regs))
    assert not req.malformed


@given(data=st.binary(max_size=300), cuts=st.lists(st.integers(0), max_size=6))
def test_the_mbap_parsers_take_any_bytes_and_raise_only_typed_errors(data: bytes, cuts: list[int]) -> None:
    requests, responses = MbapRequestParser(), MbapResponseParser(5)
    responses.expect(1, 3, 2)
    for parser in (requests, responses):
        for piece in _chunks(data, cuts):
            try:
                parser.feed(piece)
            except ModbusFrameError:
                assert parser.pending() == 0  # a false header drops what it cannot frame


def test_mbap_replies_by_transaction_unit_and_length() -> None:
    p = MbapResponseParser(5)
    p.expect(2, 3, 1)
    late = mbap_frame(1, 5, modbus.read_reply_pdu(3, [7]))
    (reply,) = p.feed(late + mbap_frame(2, 5, modbus.read_reply_pdu(3, [8])))
    assert reply.values == (8,) and p.late == 1
    p.expect(3, 3, 1)
    with pytest.raises(ModbusUnitError):
        p.feed(mbap_frame(3, 6, modbus.read_reply_pdu(3, [8])))
    p.expect(4, 3, 1)
    with pytest.raises(ModbusLengthError):
        p.feed(mbap_frame(4, 5, modbus.read_reply_pdu(3, [8, 9])))
    with pytest.raises(ModbusLengthError, match="protocol 1"):
        p.feed(b"\x00\x05\x00\x01\x00\x03\x05\x03\x02")
    with pytest.raises(ValueError):
        mbap_frame(70000, 5, b"\x03")


@pytest.mark.parametrize("code", [*ExceptionCode, 0x42])
def test_every_exception_code_is_a_typed_command_failed(code: int) -> None:
    err = modbus_exception(code, 16, device="dev", command="write")
    assert isinstance(err, ModbusException) and isinstance(err, CommandFailed)
    assert err.status == code and err.function == 16 and err.device == "dev" and err.command == "write"
    assert "write multiple registers" in str(err)
    assert (type(err) is ModbusException) == (code not in (1, 2, 3, 4, 6))
    if code in ExceptionCode.__members__.values():
        assert err.status_name == ExceptionCode(code).name.lower()


def test_out_of_range_numbers_from_the_user_are_limit_errors_naming_the_device() -> None:
    srv = socket.create_server(("127.0.0.1", 0))
    try:
        with ModbusClient.tcp(
            "127.0.0.1", srv.getsockname()[1], slave=1, device="dev", timeout=0.2
        ) as client:
            for call in (
                lambda: client.read_holding_registers(0, 0),
                lambda: client.read_holding_registers(-1, 1),
                lambda: client.write_registers(0, [70000]),
                lambda: client.write_registers(0x10000, [1]),
                lambda: client.read_write_registers(0, 126, 0, [1]),
            ):
                with pytest.raises(LimitError) as caught:
                    call()
                assert caught.value.device == "dev"
            assert client.exchanges == 0
            with pytest.raises(ValueError, match="slave id"):
                ModbusClient(client.link, slave=300)
            with pytest.raises(ValueError, match="framing"):
                ModbusClient(client.link, framing="ascii")
    finally:
        srv.close()


def test_the_register_map_refuses_what_it_lacks() -> None:
    m = RegisterMap(3, holding={0: 1, 1: 2}, read_only=[1])
    (req,) = modbus.RequestParser(3).feed(modbus.read_request(3, 0, 3))
    assert m.handle(req, 0.0) == modbus.exception_response(3, 3, 2)
    (req,) = modbus.RequestParser(3).feed(modbus.write_request(3, 0, [5, 6]))
    assert m.handle(req, 0.0) == modbus.exception_response(3, 16, 2) and m.holding[0] == 1
    (req,) = modbus.RequestParser(0).feed(modbus.write_request(0, 0, [5]))
    assert m.handle(req, 0.0) is None and m.holding[0] == 5  # a broadcast write: done, unanswered
    with pytest.raises(IllegalDataAddress):
        m.read(3, 7, 1, 0.0)
