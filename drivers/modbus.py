"""Modbus RTU, sans-IO: CRC-16/MODBUS, the frames of function codes 03, 04, 16 and 23, exception responses,
and an incremental parser for each side of the line.

Generic: the families that speak Modbus RTU (docs/protocols-robotiq.md §1, docs/protocols-schunk.md §1) use
holding and input registers, no coils. The same code builds a client's requests, the simulators' responses
and the monitor's view of either, so a simulator cannot drift from its client (an independent peer,
pymodbus, checks both in the families' tests).

A byte stream has no frame boundaries here (RTU marks them by 3.5 characters of silence, which a pty or a
TCP forwarder does not keep), so the parsers find frames by layout and CRC: a frame with a bad CRC, or bytes
that start no frame of a known layout, are dropped one byte at a time until a valid frame lines up again
(resynchronisation), and a valid frame for another slave id is consumed in silence, as a device on a shared
RS-485 line ignores it.
"""

from __future__ import annotations

import enum
import struct
from dataclasses import dataclass

__all__ = [
    "READ_HOLDING",
    "READ_INPUT",
    "READ_WRITE",
    "WRITE_MULTIPLE",
    "ExceptionCode",
    "Request",
    "RequestParser",
    "Response",
    "ResponseParser",
    "crc16",
    "exception_response",
    "read_request",
    "read_response",
    "read_write_request",
    "with_crc",
    "write_request",
    "write_response",
]

READ_HOLDING = 0x03
READ_INPUT = 0x04
WRITE_MULTIPLE = 0x10  # 16, "Preset Multiple Registers" in the Robotiq manuals
READ_WRITE = 0x17  # 23, read/write multiple registers (the write happens first)
READS = (READ_HOLDING, READ_INPUT)
FUNCTIONS = {
    READ_HOLDING: "read holding registers",
    READ_INPUT: "read input registers",
    WRITE_MULTIPLE: "write multiple registers",
    READ_WRITE: "read/write multiple registers",
}

# Quantity limits of the Modbus application protocol (V1.1b3 §6.3, §6.12, §6.17), checked both ways so a frame
# whose byte count does not fit its quantity is no frame.
MAX_READ = 125
MAX_WRITE = 123
MAX_RW_WRITE = 121


class ExceptionCode(enum.IntEnum):
    """Modbus exception codes (application protocol V1.1b3 §7) a gripper or our simulator answers."""

    ILLEGAL_FUNCTION = 0x01
    ILLEGAL_DATA_ADDRESS = 0x02
    ILLEGAL_DATA_VALUE = 0x03
    SERVER_DEVICE_FAILURE = 0x04


def _crc_table() -> tuple[int, ...]:
    table = []
    for byte in range(256):
        crc = byte
        for _ in range(8):
            crc = (crc >> 1) ^ 0xA001 if crc & 1 else crc >> 1
        table.append(crc)
    return tuple(table)


_TABLE = _crc_table()


def crc16(data: bytes | bytearray | memoryview) -> int:
    """CRC-16/MODBUS (reflected polynomial 0xA001, initial 0xFFFF); sent low byte first."""
    crc = 0xFFFF
    for byte in bytes(data):
        crc = (crc >> 8) ^ _TABLE[(crc ^ byte) & 0xFF]
    return crc


def with_crc(body: bytes) -> bytes:
    return body + struct.pack("<H", crc16(body))


def _check_slave(slave: int) -> None:
    if not 0 <= slave <= 247:
        raise ValueError(f"slave id must be 0..247, not {slave!r}")


def _registers(values: tuple[int, ...] | list[int]) -> bytes:
    for v in values:
        if not 0 <= v <= 0xFFFF:
            raise ValueError(f"a register holds 0..65535, not {v!r}")
    return struct.pack(f">{len(values)}H", *values)


# -- requests (client side) ---------------------------------------------------------------------------------


def read_request(slave: int, address: int, count: int, function: int = READ_HOLDING) -> bytes:
    """FC 03 or 04: read ``count`` registers from ``address``."""
    _check_slave(slave)
    if function not in READS or not 1 <= count <= MAX_READ:
        raise ValueError(f"read: function {function} count {count} (03 or 04, 1..{MAX_READ} registers)")
    return with_crc(struct.pack(">BBHH", slave, function, address, count))


def write_request(slave: int, address: int, values: tuple[int, ...] | list[int]) -> bytes:
    """FC 16: write ``values`` from ``address``."""
    _check_slave(slave)
    if not 1 <= len(values) <= MAX_WRITE:
        raise ValueError(f"write: 1..{MAX_WRITE} registers, not {len(values)}")
    head = struct.pack(">BBHHB", slave, WRITE_MULTIPLE, address, len(values), 2 * len(values))
    return with_crc(head + _registers(values))


def read_write_request(
    slave: int, read_address: int, read_count: int, write_address: int, values: tuple[int, ...] | list[int]
) -> bytes:
    """FC 23: write ``values`` at ``write_address``, then read ``read_count`` registers from ``read_address``
    (the device writes first)."""
    _check_slave(slave)
    if not 1 <= read_count <= MAX_READ or not 1 <= len(values) <= MAX_RW_WRITE:
        raise ValueError(f"read/write: 1..{MAX_READ} read and 1..{MAX_RW_WRITE} written registers")
    head = struct.pack(
        ">BBHHHHB", slave, READ_WRITE, read_address, read_count, write_address, len(values), 2 * len(values)
    )
    return with_crc(head + _registers(values))


# -- responses (device side) --------------------------------------------------------------------------------


def read_response(slave: int, function: int, values: tuple[int, ...] | list[int]) -> bytes:
    """The answer to FC 03, 04 or 23: a byte count and the registers read."""
    return with_crc(struct.pack(">BBB", slave, function, 2 * len(values)) + _registers(values))


def write_response(slave: int, address: int, count: int) -> bytes:
    """The answer to FC 16: the address and quantity written, echoed."""
    return with_crc(struct.pack(">BBHH", slave, WRITE_MULTIPLE, address, count))


def exception_response(slave: int, function: int, code: int) -> bytes:
    return with_crc(struct.pack(">BBB", slave, function | 0x80, code))


# -- decoded frames -----------------------------------------------------------------------------------------


@dataclass(frozen=True, slots=True)
class Request:
    """A request as a device sees it. ``address``/``count`` are the read (03, 04, 23) or, for 16, the write;
    ``write_address``/``values`` the registers written (16, 23)."""

    slave: int
    function: int
    address: int = 0
    count: int = 0
    write_address: int = 0
    values: tuple[int, ...] = ()
    raw: bytes = b""


@dataclass(frozen=True, slots=True)
class Response:
    """A response as a client sees it: registers read, the echo of a write, or an exception code."""

    slave: int
    function: int  # without the exception bit
    values: tuple[int, ...] = ()
    address: int = 0
    count: int = 0
    exception: int | None = None
    raw: bytes = b""


class _Parser:
    """Bytes in, frames out: the resynchronising core both sides share."""

    def __init__(self, slave: int | None) -> None:
        self.slave = slave  # None: every slave id (a monitor listening to the whole line)
        self._buf = bytearray()
        self.dropped = 0  # bytes thrown away while resynchronising (bad CRC, no known layout)
        self.other_slaves = 0  # valid frames for another slave id, ignored
        self.other_slave: int | None = None  # the id of the last of them (a message names it)

    def reset(self) -> None:
        """A silent interval (or a new exchange): a partial frame is abandoned."""
        self.dropped += len(self._buf)
        self._buf.clear()

    def pending(self) -> int:
        return len(self._buf)

    def _length(self, buf: bytearray) -> int | None:
        """The frame length the bytes at the start announce, 0 if they start no frame, None if unknown yet."""
        raise NotImplementedError

    def _frames(self, data: bytes) -> list[bytes]:
        self._buf += data
        out: list[bytes] = []
        buf = self._buf
        while len(buf) >= 2:
            length = self._length(buf)
            if length is None:
                break
            if length == 0:  # no layout starts here: a garbage byte
                del buf[0]
                self.dropped += 1
                continue
            if len(buf) < length:
                break
            frame = bytes(buf[:length])
            if crc16(frame[:-2]) != int.from_bytes(frame[-2:], "little"):
                del buf[0]  # a bad CRC: perhaps garbage that looked like a header; try the next byte
                self.dropped += 1
                continue
            del buf[:length]
            if self.slave is not None and frame[0] != self.slave:
                self.other_slaves += 1
                self.other_slave = frame[0]
                continue
            out.append(frame)
        return out


class RequestParser(_Parser):
    """The device's side: requests of function 03, 04, 16 and 23 (other functions of a fixed 8-byte layout,
    05 and 06, are returned too, so the device can answer them with an exception)."""

    def _length(self, buf: bytearray) -> int | None:
        fc = buf[1]
        if fc in (READ_HOLDING, READ_INPUT, 0x05, 0x06):
            return 8
        if fc == WRITE_MULTIPLE:
            if len(buf) < 7:
                return None
            count, nbytes = int.from_bytes(buf[4:6], "big"), buf[6]
            return 9 + nbytes if 1 <= count <= MAX_WRITE and nbytes == 2 * count else 0
        if fc == READ_WRITE:
            if len(buf) < 11:
                return None
            rcount, wcount, nbytes = (
                int.from_bytes(buf[4:6], "big"),
                int.from_bytes(buf[8:10], "big"),
                buf[10],
            )
            ok = 1 <= rcount <= MAX_READ and 1 <= wcount <= MAX_RW_WRITE and nbytes == 2 * wcount
            return 13 + nbytes if ok else 0
        return 0

    def feed(self, data: bytes) -> list[Request]:
        return [decode_request(f) for f in self._frames(data)]


def decode_request(frame: bytes) -> Request:
    slave, fc = frame[0], frame[1]
    if fc in (READ_HOLDING, READ_INPUT, 0x05, 0x06):
        address, count = struct.unpack(">HH", frame[2:6])
        return Request(slave, fc, address, count, raw=frame)
    if fc == WRITE_MULTIPLE:
        address, count = struct.unpack(">HH", frame[2:6])
        values = struct.unpack(f">{count}H", frame[7 : 7 + 2 * count])
        return Request(slave, fc, address, count, address, values, raw=frame)
    raddr, rcount, waddr, wcount = struct.unpack(">HHHH", frame[2:10])
    values = struct.unpack(f">{wcount}H", frame[11 : 11 + 2 * wcount])
    return Request(slave, fc, raddr, rcount, waddr, values, raw=frame)


class ResponseParser(_Parser):
    """The client's side. ``expect(function, count)`` names the one answer an exchange waits for, so a frame
    is recognised by its function and byte count, not guessed from bytes that may be garbage."""

    def __init__(self, slave: int | None) -> None:
        super().__init__(slave)
        self._function: int | None = None
        self._count = 0

    def expect(self, function: int, count: int) -> None:
        """The reply to the request just sent: ``count`` registers read, or (16) written."""
        self._function, self._count = function, count

    def _length(self, buf: bytearray) -> int | None:
        fc = buf[1]
        wanted = self._function
        if fc & 0x80:
            return 5 if wanted is None or fc & 0x7F == wanted else 0
        if wanted is not None and fc != wanted:
            return 0
        if fc == WRITE_MULTIPLE:
            return 8
        if fc in (READ_HOLDING, READ_INPUT, READ_WRITE):
            if len(buf) < 3:
                return None
            nbytes = buf[2]
            if wanted is not None:
                return 5 + nbytes if nbytes == 2 * self._count else 0
            return 5 + nbytes if nbytes % 2 == 0 and 2 <= nbytes <= 2 * MAX_READ else 0
        return 0

    def feed(self, data: bytes) -> list[Response]:
        return [decode_response(f) for f in self._frames(data)]


def decode_response(frame: bytes) -> Response:
    slave, fc = frame[0], frame[1]
    if fc & 0x80:
        return Response(slave, fc & 0x7F, exception=frame[2], raw=frame)
    if fc == WRITE_MULTIPLE:
        address, count = struct.unpack(">HH", frame[2:6])
        return Response(slave, fc, address=address, count=count, raw=frame)
    n = frame[2] // 2
    return Response(slave, fc, struct.unpack(f">{n}H", frame[3 : 3 + 2 * n]), count=n, raw=frame)


def wire_seconds(nbytes: int, baudrate: int = 115200, bits_per_char: int = 10) -> float:
    """Time ``nbytes`` take on the line (8N1: 10 bits per character)."""
    return nbytes * bits_per_char / baudrate


def silent_interval(baudrate: int = 115200) -> float:
    """t3.5, the silence that ends an RTU frame: 3.5 characters, fixed at 1.75 ms above 19200 baud (Modbus
    over serial line V1.02 §2.5.1.1)."""
    return 0.00175 if baudrate > 19200 else 3.5 * 11 / baudrate
