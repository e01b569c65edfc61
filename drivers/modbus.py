"""Modbus, sans-IO: the PDUs of function codes 03, 04, 16 and 23, exception responses, the typed errors a
frame or an answer can raise, and RTU framing (CRC-16/MODBUS) with an incremental parser for each side of the
line. Modbus TCP's MBAP framing of the same PDUs is :mod:`.modbus_tcp`.

Generic: the families that speak Modbus (docs/protocols-robotiq.md §1, docs/protocols-schunk.md §1) use
holding and input registers, no coils. The same code builds a client's requests, the simulators' responses
and the monitor's view of either, so a simulator cannot drift from its client (an independent peer,
pymodbus, checks both in the tests). Sources: Modbus Application Protocol Specification V1.1b3 (the PDUs,
§6 and §7) and Modbus over Serial Line Specification V1.02 (RTU framing, §2.5).

A byte stream has no frame boundaries here (RTU marks them by 3.5 characters of silence, which a pty or a
TCP forwarder does not keep), so the RTU parsers find frames by layout and CRC: a frame with a bad CRC, or
bytes that start no frame of a known layout, are dropped one byte at a time until a valid frame lines up
again (resynchronisation), and a valid frame for another slave id is consumed in silence, as a device on a
shared RS-485 line ignores it. What was dropped is kept as a typed error (:attr:`_Parser.last_error`), so a
client that then times out can say why; :func:`decode_rtu` checks one whole frame and raises it.
"""

from __future__ import annotations

import enum
import struct
from dataclasses import dataclass

from .errors import CommandFailed, ProtocolError

__all__ = [
    "READ_HOLDING",
    "READ_INPUT",
    "READ_WRITE",
    "WRITE_MULTIPLE",
    "ExceptionCode",
    "IllegalDataAddress",
    "IllegalDataValue",
    "IllegalFunction",
    "ModbusCRCError",
    "ModbusException",
    "ModbusFrameError",
    "ModbusLengthError",
    "ModbusUnitError",
    "Request",
    "RequestParser",
    "Response",
    "ResponseParser",
    "ServerDeviceBusy",
    "ServerDeviceFailure",
    "crc16",
    "decode_rtu",
    "exception_response",
    "modbus_exception",
    "read_request",
    "read_response",
    "read_write_request",
    "rtu_frame",
    "with_crc",
    "write_request",
    "write_response",
]

READ_HOLDING = 0x03
READ_INPUT = 0x04
WRITE_MULTIPLE = 0x10  # 16, "Preset Multiple Registers" in the Robotiq manuals
READ_WRITE = 0x17  # 23, read/write multiple registers (the write happens first)
READS = (READ_HOLDING, READ_INPUT)
WRITES = (WRITE_MULTIPLE, READ_WRITE)
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
    """Modbus exception codes (application protocol V1.1b3 §7)."""

    ILLEGAL_FUNCTION = 0x01
    ILLEGAL_DATA_ADDRESS = 0x02
    ILLEGAL_DATA_VALUE = 0x03
    SERVER_DEVICE_FAILURE = 0x04
    ACKNOWLEDGE = 0x05
    SERVER_DEVICE_BUSY = 0x06
    MEMORY_PARITY_ERROR = 0x08
    GATEWAY_PATH_UNAVAILABLE = 0x0A
    GATEWAY_TARGET_FAILED = 0x0B


# -- typed errors --------------------------------------------------------------------------------------------


class ModbusFrameError(ProtocolError):
    """Bytes that are no Modbus frame for this exchange (a :class:`~grippers.ProtocolError`)."""


class ModbusCRCError(ModbusFrameError):
    """An RTU frame whose CRC does not match its bytes (noise on the line, a broken adapter)."""


class ModbusLengthError(ModbusFrameError):
    """A frame whose length does not fit its function (a byte count or an MBAP length field that lies)."""


class ModbusUnitError(ModbusFrameError):
    """A reply from another slave (unit) id than the request's: ``unit`` is the id that answered."""

    def __init__(self, message: str, *, unit: int, device: str | None = None, command: str | None = None):
        self.unit = unit
        super().__init__(message, device=device, command=command)


class ModbusException(CommandFailed):
    """The device answered a Modbus exception: ``status`` is its code, ``status_name`` the code's name in
    lower case, ``function`` the function code it refused. Each code of :class:`ExceptionCode` that a
    register device answers has a subclass; :func:`modbus_exception` picks it."""

    code: ExceptionCode | None = None

    def __init__(
        self,
        message: str = "",
        *,
        status: int | None = None,
        function: int = 0,
        status_name: str | None = None,
        device: str | None = None,
        command: str | None = None,
    ) -> None:
        self.function = function
        status = status if status is not None else (int(self.code) if self.code is not None else 0)
        name = status_name or _code_name(status)
        super().__init__(
            message or f"Modbus exception {status} ({name})",
            status=status,
            status_name=name,
            device=device,
            command=command,
        )


class IllegalFunction(ModbusException):
    code = ExceptionCode.ILLEGAL_FUNCTION


class IllegalDataAddress(ModbusException):
    code = ExceptionCode.ILLEGAL_DATA_ADDRESS


class IllegalDataValue(ModbusException):
    code = ExceptionCode.ILLEGAL_DATA_VALUE


class ServerDeviceFailure(ModbusException):
    code = ExceptionCode.SERVER_DEVICE_FAILURE


class ServerDeviceBusy(ModbusException):
    code = ExceptionCode.SERVER_DEVICE_BUSY


_EXCEPTIONS: dict[int, type[ModbusException]] = {
    cls.code: cls
    for cls in (IllegalFunction, IllegalDataAddress, IllegalDataValue, ServerDeviceFailure, ServerDeviceBusy)
    if cls.code is not None
}


def _code_name(code: int) -> str:
    try:
        return ExceptionCode(code).name.lower()
    except ValueError:
        return f"exception_0x{code:02x}"


def modbus_exception(
    code: int, function: int, *, device: str | None = None, command: str | None = None
) -> ModbusException:
    """The typed error of exception ``code`` answered to ``function`` (the base class for a code without
    a subclass of its own), its message naming both."""
    cls = _EXCEPTIONS.get(code, ModbusException)
    what = FUNCTIONS.get(function, f"function {function}")
    return cls(
        f"the device answered Modbus exception {code} ({_code_name(code)}) to {what}",
        status=code,
        function=function,
        device=device,
        command=command,
    )


# -- CRC and PDUs --------------------------------------------------------------------------------------------


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
    """CRC-16/MODBUS (reflected polynomial 0xA001, initial 0xFFFF; serial line V1.02 §6.2.2); sent low byte
    first."""
    crc = 0xFFFF
    for byte in bytes(data):
        crc = (crc >> 8) ^ _TABLE[(crc ^ byte) & 0xFF]
    return crc


def with_crc(body: bytes) -> bytes:
    return body + struct.pack("<H", crc16(body))


def check_slave(slave: int) -> None:
    """0 (broadcast) to 247: serial line V1.02 §2.2; Modbus TCP's unit id is one byte as well."""
    if not isinstance(slave, int) or not 0 <= slave <= 247:
        raise ValueError(f"slave id must be 0..247, not {slave!r}")


def _registers(values: tuple[int, ...] | list[int]) -> bytes:
    for v in values:
        if not isinstance(v, int) or not 0 <= v <= 0xFFFF:
            raise ValueError(f"a register holds 0..65535, not {v!r}")
    return struct.pack(f">{len(values)}H", *values)


def _address(address: int) -> None:
    if not isinstance(address, int) or not 0 <= address <= 0xFFFF:
        raise ValueError(f"a register address is 0..65535, not {address!r}")


def read_pdu(address: int, count: int, function: int = READ_HOLDING) -> bytes:
    """FC 03 or 04: read ``count`` registers from ``address``."""
    _address(address)
    if function not in READS or not isinstance(count, int) or not 1 <= count <= MAX_READ:
        raise ValueError(f"read: function {function} count {count} (03 or 04, 1..{MAX_READ} registers)")
    return struct.pack(">BHH", function, address, count)


def write_pdu(address: int, values: tuple[int, ...] | list[int]) -> bytes:
    """FC 16: write ``values`` from ``address``."""
    _address(address)
    if not 1 <= len(values) <= MAX_WRITE:
        raise ValueError(f"write: 1..{MAX_WRITE} registers, not {len(values)}")
    head = struct.pack(">BHHB", WRITE_MULTIPLE, address, len(values), 2 * len(values))
    return head + _registers(values)


def read_write_pdu(
    read_address: int, read_count: int, write_address: int, values: tuple[int, ...] | list[int]
) -> bytes:
    """FC 23: write ``values`` at ``write_address``, then read ``read_count`` registers from
    ``read_address`` (the device writes first)."""
    _address(read_address)
    _address(write_address)
    if not 1 <= read_count <= MAX_READ or not 1 <= len(values) <= MAX_RW_WRITE:
        raise ValueError(f"read/write: 1..{MAX_READ} read and 1..{MAX_RW_WRITE} written registers")
    head = struct.pack(
        ">BHHHHB", READ_WRITE, read_address, read_count, write_address, len(values), 2 * len(values)
    )
    return head + _registers(values)


def read_reply_pdu(function: int, values: tuple[int, ...] | list[int]) -> bytes:
    """The answer to FC 03, 04 or 23: a byte count and the registers read."""
    return struct.pack(">BB", function, 2 * len(values)) + _registers(values)


def write_reply_pdu(address: int, count: int) -> bytes:
    """The answer to FC 16: the address and quantity written, echoed."""
    return struct.pack(">BHH", WRITE_MULTIPLE, address, count)


def exception_pdu(function: int, code: int) -> bytes:
    return struct.pack(">BB", (function | 0x80) & 0xFF, code)


def request_pdu_length(pdu: bytes | bytearray) -> int | None:
    """The length of the request PDU that ``pdu`` starts (at least one byte): 0 if no known layout starts
    there (an unknown function, a byte count that does not fit its quantity), None if more bytes are needed.
    Functions 05 and 06 (a fixed five bytes) are framed too, so a device can refuse them."""
    fc = pdu[0]
    if fc in (READ_HOLDING, READ_INPUT, 0x05, 0x06):
        return 5
    if fc == WRITE_MULTIPLE:
        if len(pdu) < 6:
            return None
        count, nbytes = int.from_bytes(pdu[3:5], "big"), pdu[5]
        return 6 + nbytes if 1 <= count <= MAX_WRITE and nbytes == 2 * count else 0
    if fc == READ_WRITE:
        if len(pdu) < 10:
            return None
        rcount, wcount, nbytes = int.from_bytes(pdu[3:5], "big"), int.from_bytes(pdu[7:9], "big"), pdu[9]
        ok = 1 <= rcount <= MAX_READ and 1 <= wcount <= MAX_RW_WRITE and nbytes == 2 * wcount
        return 10 + nbytes if ok else 0
    return 0


def response_pdu_length(pdu: bytes | bytearray, function: int | None = None, count: int = 0) -> int | None:
    """The length of the response PDU that ``pdu`` starts, as :func:`request_pdu_length`. ``function`` and
    ``count`` name the one answer an exchange waits for (None: any), so a frame is recognised by its
    function and byte count, not guessed from bytes that may be garbage."""
    fc = pdu[0]
    if fc & 0x80:
        return 2 if function is None or fc & 0x7F == function else 0
    if function is not None and fc != function:
        return 0
    if fc == WRITE_MULTIPLE:
        return 5
    if fc in (READ_HOLDING, READ_INPUT, READ_WRITE):
        if len(pdu) < 2:
            return None
        nbytes = pdu[1]
        if function is not None:
            return 2 + nbytes if nbytes == 2 * count else 0
        return 2 + nbytes if nbytes % 2 == 0 and 2 <= nbytes <= 2 * MAX_READ else 0
    return 0


# -- decoded frames ------------------------------------------------------------------------------------------


@dataclass(frozen=True, slots=True)
class Request:
    """A request as a device sees it. ``address``/``count`` are the read (03, 04, 23) or, for 16, the write;
    ``write_address``/``values`` the registers written (16, 23); ``transaction`` Modbus TCP's id (0 on RTU);
    ``malformed``: a PDU of this function whose length does not fit it (Modbus TCP frames it by length)."""

    slave: int
    function: int
    address: int = 0
    count: int = 0
    write_address: int = 0
    values: tuple[int, ...] = ()
    raw: bytes = b""
    transaction: int = 0
    malformed: bool = False


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
    transaction: int = 0


def decode_request_pdu(slave: int, pdu: bytes, raw: bytes, transaction: int = 0) -> Request:
    """A whole request PDU (its length checked by :func:`request_pdu_length`)."""
    fc = pdu[0]
    if fc in (READ_HOLDING, READ_INPUT, 0x05, 0x06):
        address, count = struct.unpack(">HH", pdu[1:5])
        return Request(slave, fc, address, count, raw=raw, transaction=transaction)
    if fc == WRITE_MULTIPLE:
        address, count = struct.unpack(">HH", pdu[1:5])
        values = struct.unpack(f">{count}H", pdu[6 : 6 + 2 * count])
        return Request(slave, fc, address, count, address, values, raw=raw, transaction=transaction)
    raddr, rcount, waddr, wcount = struct.unpack(">HHHH", pdu[1:9])
    values = struct.unpack(f">{wcount}H", pdu[10 : 10 + 2 * wcount])
    return Request(slave, fc, raddr, rcount, waddr, values, raw=raw, transaction=transaction)


def decode_response_pdu(slave: int, pdu: bytes, raw: bytes, transaction: int = 0) -> Response:
    """A whole response PDU (its length checked by :func:`response_pdu_length`)."""
    fc = pdu[0]
    if fc & 0x80:
        return Response(slave, fc & 0x7F, exception=pdu[1], raw=raw, transaction=transaction)
    if fc == WRITE_MULTIPLE:
        address, count = struct.unpack(">HH", pdu[1:5])
        return Response(slave, fc, address=address, count=count, raw=raw, transaction=transaction)
    n = pdu[1] // 2
    values = struct.unpack(f">{n}H", pdu[2 : 2 + 2 * n])
    return Response(slave, fc, values, count=n, raw=raw, transaction=transaction)


# -- RTU framing ---------------------------------------------------------------------------------------------


def rtu_frame(slave: int, pdu: bytes) -> bytes:
    """An RTU frame: the slave id, the PDU, the CRC (serial line V1.02 §2.5.1)."""
    check_slave(slave)
    return with_crc(bytes([slave]) + pdu)


def read_request(slave: int, address: int, count: int, function: int = READ_HOLDING) -> bytes:
    return rtu_frame(slave, read_pdu(address, count, function))


def write_request(slave: int, address: int, values: tuple[int, ...] | list[int]) -> bytes:
    return rtu_frame(slave, write_pdu(address, values))


def read_write_request(
    slave: int, read_address: int, read_count: int, write_address: int, values: tuple[int, ...] | list[int]
) -> bytes:
    return rtu_frame(slave, read_write_pdu(read_address, read_count, write_address, values))


def read_response(slave: int, function: int, values: tuple[int, ...] | list[int]) -> bytes:
    return rtu_frame(slave, read_reply_pdu(function, values))


def write_response(slave: int, address: int, count: int) -> bytes:
    return rtu_frame(slave, write_reply_pdu(address, count))


def exception_response(slave: int, function: int, code: int) -> bytes:
    return rtu_frame(slave, exception_pdu(function, code))


def decode_rtu(
    frame: bytes, *, slave: int | None = None, function: int | None = None, count: int = 0
) -> Response:
    """One whole RTU response frame, checked: :class:`ModbusLengthError` when its length does not fit its
    function (or the ``function`` and ``count`` expected), :class:`ModbusCRCError`, :class:`ModbusUnitError`
    when it comes from another id than ``slave``. An exception response is returned (its ``exception``
    set): :func:`modbus_exception` makes it an error."""
    frame = bytes(frame)
    length = response_pdu_length(frame[1:], function, count) if len(frame) >= 2 else None
    if not length or len(frame) != length + 3:
        raise ModbusLengthError(f"{len(frame)} bytes are no Modbus RTU reply ({frame[:8].hex(' ')})")
    if crc16(frame[:-2]) != int.from_bytes(frame[-2:], "little"):
        raise ModbusCRCError(f"bad CRC in {frame.hex(' ')}")
    if slave is not None and frame[0] != slave:
        raise ModbusUnitError(f"slave {frame[0]} answered, not {slave}", unit=frame[0])
    return decode_response_pdu(frame[0], frame[1:-2], frame)


class _Parser:
    """Bytes in, RTU frames out: the resynchronising core both sides share."""

    def __init__(self, slave: int | None) -> None:
        self.slave = slave  # None: every slave id (a monitor listening to the whole line)
        self._buf = bytearray()
        self.dropped = 0  # bytes thrown away while resynchronising (bad CRC, no known layout)
        self.other_slaves = 0  # valid frames for another slave id, ignored
        self.other_slave: int | None = None  # the id of the last of them (a message names it)
        self.last_error: ModbusFrameError | None = None  # why bytes were dropped last (a CRC, a length)

    def reset(self) -> None:
        """A silent interval (or a new exchange): a partial frame is abandoned."""
        self.dropped += len(self._buf)
        self._buf.clear()
        self.last_error = None

    def pending(self) -> int:
        return len(self._buf)

    def _length(self, pdu: bytearray) -> int | None:
        """The PDU length the bytes at the start announce, 0 if they start no PDU, None if unknown yet."""
        raise NotImplementedError

    def _drop(self, buf: bytearray, error: ModbusFrameError | None) -> None:
        del buf[0]
        self.dropped += 1
        if error is not None:
            self.last_error = error

    def _frames(self, data: bytes) -> list[bytes]:
        self._buf += data
        out: list[bytes] = []
        buf = self._buf
        while len(buf) >= 2:
            pdu_length = self._length(buf[1:])
            if pdu_length is None:
                break
            if pdu_length == 0:  # no layout starts here: a garbage byte
                ours = self.slave is not None and buf[0] == self.slave and buf[1] & 0x7F in FUNCTIONS
                head = bytes(buf[:3]).hex(" ")
                self._drop(
                    buf, ModbusLengthError(f"a frame of the wrong length ({head} ...)") if ours else None
                )
                continue
            length = pdu_length + 3
            if len(buf) < length:
                break
            frame = bytes(buf[:length])
            if crc16(frame[:-2]) != int.from_bytes(frame[-2:], "little"):
                # a bad CRC: perhaps garbage that looked like a header; try the next byte
                ours = self.slave is None or frame[0] == self.slave
                self._drop(buf, ModbusCRCError(f"bad CRC in {frame.hex(' ')}") if ours else None)
                continue
            del buf[:length]
            if self.slave is not None and frame[0] != self.slave:
                self.other_slaves += 1
                self.other_slave = frame[0]
                self.last_error = ModbusUnitError(f"slave {frame[0]} answered", unit=frame[0])
                continue
            out.append(frame)
        return out


class RequestParser(_Parser):
    """The device's side: requests of function 03, 04, 16 and 23 (other functions of a fixed 8-byte layout,
    05 and 06, are returned too, so the device can answer them with an exception)."""

    def _length(self, pdu: bytearray) -> int | None:
        return request_pdu_length(pdu)

    def feed(self, data: bytes) -> list[Request]:
        return [decode_request(f) for f in self._frames(data)]


def decode_request(frame: bytes) -> Request:
    return decode_request_pdu(frame[0], frame[1:-2], frame)


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

    def _length(self, pdu: bytearray) -> int | None:
        return response_pdu_length(pdu, self._function, self._count)

    def feed(self, data: bytes) -> list[Response]:
        return [decode_response(f) for f in self._frames(data)]


def decode_response(frame: bytes) -> Response:
    return decode_response_pdu(frame[0], frame[1:-2], frame)


def wire_seconds(nbytes: int, baudrate: int = 115200, bits_per_char: int = 10) -> float:
    """Time ``nbytes`` take on the line (8N1: 10 bits per character)."""
    return nbytes * bits_per_char / baudrate


def silent_interval(baudrate: int = 115200) -> float:
    """t3.5, the silence that ends an RTU frame: 3.5 characters, fixed at 1.75 ms above 19200 baud (Modbus
    over serial line V1.02 §2.5.1.1)."""
    return 0.00175 if baudrate > 19200 else 3.5 * 11 / baudrate
