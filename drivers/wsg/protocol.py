"""WSG packet layer: checksum, packet codec, incremental parser and status codes (sans-IO).

Both the client and the simulator frame bytes with this module, so the byte layout exists exactly once.
The parser never raises on input: a reader thread must survive any garbage on the line, so problems come
back as typed events next to the packets instead of exceptions.
"""

from __future__ import annotations

import struct
from collections.abc import Callable
from dataclasses import dataclass
from enum import IntEnum
from typing import Any

from ..errors import ProtocolError

__all__ = [
    "CRC_TABLE",
    "HEADER_SIZE",
    "MAX_PAYLOAD",
    "PREAMBLE",
    "BadLength",
    "ChecksumError",
    "Discarded",
    "Packet",
    "PacketParser",
    "ParseEvent",
    "Status",
    "can_frames",
    "crc16",
    "decode_packet",
    "encode_packet",
    "status_name",
    "to_status",
    "whole_packet",
]

# WSG manual 4.0.x §1.2.1: AA AA AA, id (u8), size (u16 LE), payload, checksum (u16, low byte first).
PREAMBLE = b"\xaa\xaa\xaa"
HEADER_SIZE = 6  # preamble + id + size
TRAILER_SIZE = 2  # checksum
# The largest payload the parser accepts. The manuals' largest fixed reply is 34 bytes (53h), loop data is at
# most 256 bytes (06h) and finger data frames are small; a size field beyond this is treated as corrupt so a
# receiver does not wait for hundreds of bytes that belong to later packets.
MAX_PAYLOAD = 1024

_HEADER = struct.Struct("<3sBH")
_U16 = struct.Struct("<H")

# docs/protocols.md §1 "Framing and checksum": the manuals' table is the MSB-first table of polynomial 0x1021,
# applied with a right-shifting update starting at 0xFFFF. Generated here rather than transcribed, because the
# printed 4.0.x table has a typo at 0x59 (0xcdbc for 0xcbdc).
CRC_POLYNOMIAL = 0x1021
CRC_INIT = 0xFFFF


def _make_table() -> tuple[int, ...]:
    table = []
    for i in range(256):
        crc = i << 8
        for _ in range(8):
            crc = ((crc << 1) ^ CRC_POLYNOMIAL) if crc & 0x8000 else (crc << 1)
        table.append(crc & 0xFFFF)
    return tuple(table)


CRC_TABLE: tuple[int, ...] = _make_table()


def crc16(data: bytes | bytearray | memoryview, crc: int = CRC_INIT) -> int:
    """The WSG checksum of ``data`` continuing from ``crc``; over a whole packet with its checksum: 0."""
    table = CRC_TABLE
    for byte in data:
        crc = table[(crc & 0xFF) ^ byte] ^ (crc >> 8)  # = table[(crc ^ byte) & 0xFF]: byte < 256, one op less
    return crc


# docs/protocols.md §1: the state after the three preamble bytes; lets the parser skip them on every packet.
CRC_AFTER_PREAMBLE = crc16(PREAMBLE)


def encode_packet(command: int, payload: bytes = b"") -> bytes:
    """A whole packet, preamble to checksum."""
    if not 0 <= command <= 0xFF:
        raise ProtocolError(f"command id {command!r} does not fit in one byte")
    if len(payload) > 0xFFFF:
        raise ProtocolError(f"payload of {len(payload)} bytes does not fit the u16 size field")
    head = _HEADER.pack(PREAMBLE, command, len(payload))
    crc = crc16(payload, crc16(head[3:], CRC_AFTER_PREAMBLE))
    return b"".join((head, payload, _U16.pack(crc)))


@dataclass(frozen=True, slots=True)
class Packet:
    """One packet as received or to be sent; for replies the payload starts with the u16 status."""

    command: int
    payload: bytes = b""

    def __init__(self, command: int, payload: bytes = b"") -> None:
        # One per packet received: the slot setters take half the time of the object.__setattr__ calls of
        # the generated frozen __init__ (docs/performance.md, target 2); the instance stays frozen.
        _set_command(self, command)
        _set_payload(self, payload)

    @property
    def status(self) -> int:
        # WSG manual 4.0.x §1.2.2: every reply starts with a u16 LE status code.
        if len(self.payload) < 2:
            raise ProtocolError(
                f"reply of {len(self.payload)} bytes has no status code", command=f"{self.command:02X}h"
            )
        return self.payload[0] | (self.payload[1] << 8)

    @property
    def data(self) -> bytes:
        return self.payload[2:]

    def encode(self) -> bytes:
        return encode_packet(self.command, self.payload)


def slot_setter(cls: type, name: str) -> Callable[[Any, Any], None]:
    """The setter of the slot ``name`` of a frozen slotted class, so that a parser fills its instances
    without ``__init__`` (the fast path, benchmark 4); from the class's own ``__dict__``, where the slot's
    descriptor lives, so no type checker has to be told to look away."""
    setter: Callable[[Any, Any], None] = cls.__dict__[name].__set__
    return setter


_set_command = slot_setter(Packet, "command")
_set_payload = slot_setter(Packet, "payload")


def whole_packet(
    data: bytes | bytearray | memoryview, verify_checksum: bool = True, max_payload: int = MAX_PAYLOAD
) -> Packet | None:
    """``data`` as exactly one whole, valid packet; None for anything else (a stream needs the parser).

    Why a function of its own: on TCP and UDP a received chunk is nearly always exactly one reply, and the
    client checks the reply it reads for itself with this alone (docs/performance.md, target 2). It accepts
    only what :class:`PacketParser` would turn into this one packet, so a None costs nothing but the rescan.
    """
    n = len(data)
    if n < HEADER_SIZE + TRAILER_SIZE:
        return None
    size = data[4] | (data[5] << 8)
    if (
        n != HEADER_SIZE + size + TRAILER_SIZE
        or size > max_payload
        or data[3] == 0xAA
        or data[:3] != PREAMBLE
    ):
        return None
    if verify_checksum:
        crc = CRC_AFTER_PREAMBLE
        table = CRC_TABLE
        for byte in data[3:]:  # crc16() inlined: the call costs ~10 % of the check
            crc = table[(crc & 0xFF) ^ byte] ^ (crc >> 8)
        if crc:
            return None
    return Packet(data[3], bytes(data[HEADER_SIZE:-TRAILER_SIZE]))


def decode_packet(raw: bytes, *, verify_checksum: bool = True) -> Packet:
    """Decode exactly one whole packet (strict: for tests, captures and tools, not for streams)."""
    if len(raw) < HEADER_SIZE + TRAILER_SIZE or raw[:3] != PREAMBLE:
        raise ProtocolError(f"not a WSG packet: {bytes(raw[:16]).hex(' ')}")
    _, command, size = _HEADER.unpack_from(raw)
    if len(raw) != HEADER_SIZE + size + TRAILER_SIZE:
        raise ProtocolError(f"size field says {size} payload bytes, packet holds {len(raw) - 8}")
    if verify_checksum and crc16(raw) != 0:
        raise ProtocolError("checksum mismatch", command=f"{command:02X}h")
    return Packet(command, bytes(raw[HEADER_SIZE:-TRAILER_SIZE]))


# ---------------------------------------------------------------------------------------------- parse events


@dataclass(frozen=True, slots=True)
class ChecksumError:
    """A complete candidate packet with a wrong checksum (dropped; the scan resumes after its preamble)."""

    command: int
    payload: bytes
    received: int
    expected: int
    raw: bytes


@dataclass(frozen=True, slots=True)
class BadLength:
    """A header whose size field exceeds ``max_payload``: a false preamble in noise or a corrupted size."""

    command: int
    size: int
    max_payload: int
    raw: bytes


@dataclass(frozen=True, slots=True)
class Discarded:
    """Bytes skipped while looking for a preamble, or a partial packet dropped by ``reset()``."""

    raw: bytes
    reason: str


ParseEvent = ChecksumError | BadLength | Discarded


class PacketParser:
    """Incremental WSG packet parser: feed it any chunks, get packets and events back; never raises.

    Resynchronisation (docs/protocols.md §1): a preamble is the LAST three bytes of a run of 0xAA (so a stray
    0xAA before a packet costs nothing; command id 0xAA cannot be framed, and no WSG command uses it).
    Nothing is consumed until a packet checks out: on a checksum failure or an impossible size the scan
    restarts right after the false preamble, so a false preamble in noise never swallows the real packets
    behind it. A plausible but wrong size field can still make the parser wait; :meth:`reset` after a silent
    gap (what the device itself does) gives those bytes back to the scan.
    """

    __slots__ = ("_buf", "_max_payload", "_max_size", "_pending", "_verify")

    def __init__(
        self,
        verify_checksum: bool = True,
        max_payload: int = MAX_PAYLOAD,
        max_size: Callable[[int], int] | None = None,
    ) -> None:
        self._buf = bytearray()
        self._verify = verify_checksum
        self._max_payload = max_payload
        # Per command id: the largest payload a packet of that id can carry now (docs/protocols.md §1).
        # On a stream without silent gaps (TCP, CAN) this is what bounds how long a false header with a
        # plausible size can hold back the packets behind it.
        self._max_size = max_size
        self._pending: list[Packet | ParseEvent] = []

    @property
    def buffered(self) -> int:
        """Bytes held for a packet that is not complete yet."""
        return len(self._buf)

    @property
    def verify_checksum(self) -> bool:
        return self._verify

    @property
    def max_payload(self) -> int:
        return self._max_payload

    def feed(self, data: bytes | bytearray | memoryview = b"") -> list[Packet | ParseEvent]:
        out = self._pending
        self._pending = []
        buf = self._buf
        if not buf and not out and (packet := whole_packet(data, self._verify, self._max_payload)):
            # The usual chunk on TCP and UDP is exactly one whole packet: decoded without the buffer and the
            # scan (half the parsing cost of a reply). The general path gives the same result for it.
            return [packet]
        if data:
            buf += data
        if buf:
            self._scan(out)
        return out

    def reset(self) -> bytes:
        """Drop a half-received packet (after a silent gap) and rescan the bytes behind its preamble.

        Returns the dropped bytes. Packets and events found in the rest come out of the next :meth:`feed`
        (``feed(b"")`` collects them at once).
        """
        buf = self._buf
        if not buf:
            return b""
        if buf.startswith(PREAMBLE):
            dropped = bytes(buf[:3])
            del buf[:3]
        else:  # only trailing 0xAA bytes of an unfinished preamble
            dropped = bytes(buf)
            buf.clear()
        self._pending.append(Discarded(dropped, "partial packet dropped after a silent gap"))
        if buf:
            self._scan(self._pending)
        return dropped

    def _scan(self, out: list[Packet | ParseEvent]) -> None:
        buf = self._buf
        n = len(buf)
        pos = 0
        find = buf.find
        verify = self._verify
        max_payload = self._max_payload
        max_size = self._max_size
        table = CRC_TABLE
        while True:
            start = find(PREAMBLE, pos)
            if start < 0:
                # Keep at most two trailing 0xAA bytes: the start of a preamble still arriving.
                keep = n
                floor = max(pos, n - 2)
                while keep > floor and buf[keep - 1] == 0xAA:
                    keep -= 1
                if keep > pos:
                    out.append(Discarded(bytes(buf[pos:keep]), "noise"))
                pos = keep
                break
            # Extend over the whole run of 0xAA; the packet starts at its last three bytes.
            j = start + 3
            while j < n and buf[j] == 0xAA:
                j += 1
            start = j - 3
            if start > pos:
                out.append(Discarded(bytes(buf[pos:start]), "noise"))
            pos = start
            if n - start < HEADER_SIZE:
                break  # header incomplete (or the 0xAA run may still go on)
            command = buf[start + 3]
            size = buf[start + 4] | (buf[start + 5] << 8)
            limit = max_payload if max_size is None else min(max_payload, max_size(command))
            if size > limit:
                out.append(BadLength(command, size, limit, bytes(buf[start : start + HEADER_SIZE])))
                pos = start + 3
                continue
            end = start + HEADER_SIZE + size + TRAILER_SIZE
            if end > n:
                break  # wait for the rest
            if verify:
                # crc16() inlined (a call per packet costs ~10 % here); iterating a bytearray slice copy is
                # faster than iterating a memoryview of the buffer
                crc = CRC_AFTER_PREAMBLE
                for byte in buf[start + 3 : end]:
                    crc = table[(crc & 0xFF) ^ byte] ^ (crc >> 8)
                if crc:
                    raw = bytes(buf[start:end])
                    received = raw[-2] | (raw[-1] << 8)
                    out.append(
                        ChecksumError(command, raw[HEADER_SIZE:-TRAILER_SIZE], received, crc16(raw[:-2]), raw)
                    )
                    pos = start + 3  # rescan right after the false preamble, not after the claimed length
                    continue
            out.append(Packet(command, bytes(buf[start + HEADER_SIZE : end - TRAILER_SIZE])))
            pos = end
        if pos:
            del buf[:pos]


def can_frames(packet: bytes, frame_size: int = 8) -> list[bytes]:
    """Cut a whole packet into CAN data fields of 8 bytes, the last one shorter (docs/protocols.md §1, CAN).

    The receiver reassembles by feeding the frames' data to a :class:`PacketParser`, which ends a packet by
    its size field, not by a short frame (a packet whose length is a multiple of 8 ends on a full frame).
    """
    return [packet[i : i + frame_size] for i in range(0, len(packet), frame_size)]


# ---------------------------------------------------------------------------------------------- status codes


class Status(IntEnum):
    """Status codes, WSG manual 4.0.x Appendix A (identical in 2.2.0 Appendix A)."""

    E_SUCCESS = 0
    E_NOT_AVAILABLE = 1
    E_NO_SENSOR = 2
    E_NOT_INITIALIZED = 3
    E_ALREADY_RUNNING = 4
    E_FEATURE_NOT_SUPPORTED = 5
    E_INCONSISTENT_DATA = 6
    E_TIMEOUT = 7
    E_READ_ERROR = 8
    E_WRITE_ERROR = 9
    E_INSUFFICIENT_RESOURCES = 10
    E_CHECKSUM_ERROR = 11
    E_NO_PARAM_EXPECTED = 12
    E_NOT_ENOUGH_PARAMS = 13
    E_CMD_UNKNOWN = 14
    E_CMD_FORMAT_ERROR = 15
    E_ACCESS_DENIED = 16
    E_ALREADY_OPEN = 17
    E_CMD_FAILED = 18
    E_CMD_ABORTED = 19
    E_INVALID_HANDLE = 20
    E_NOT_FOUND = 21
    E_NOT_OPEN = 22
    E_IO_ERROR = 23
    E_INVALID_PARAMETER = 24
    E_INDEX_OUT_OF_BOUNDS = 25
    E_CMD_PENDING = 26
    E_OVERRUN = 27
    E_RANGE_ERROR = 28
    E_AXIS_BLOCKED = 29
    E_FILE_EXISTS = 30

    @property
    def meaning(self) -> str:
        return _MEANINGS[self.value]

    @staticmethod
    def describe(code: int) -> str:
        """``"E_NAME: meaning"`` for a known code, ``"status N (unknown)"`` otherwise; never raises."""
        meaning = _MEANINGS.get(int(code))
        if meaning is None:
            return f"status {int(code)} (unknown)"
        return f"{Status(code).name}: {meaning}"


# WSG manual 4.0.x Appendix A, "Description" column.
_MEANINGS: dict[int, str] = {
    0: "No error occurred, operation was successful",
    1: "Function or data is not available",
    2: "No measurement converter is connected",
    3: "Device was not initialized",
    4: "The data acquisition is already running",
    5: "The requested feature is currently not available",
    6: "One or more parameters are inconsistent",
    7: "Timeout error",
    8: "Error while reading data",
    9: "Error while writing data",
    10: "No more memory available",
    11: "Checksum error",
    12: "A Parameter was given, but none expected",
    13: "Not enough parameters for executing the command",
    14: "Unknown command",
    15: "Command format error",
    16: "Access denied",
    17: "Interface is already open",
    18: "Error while executing a command",
    19: "Command execution was aborted by the user",
    20: "Invalid handle",
    21: "Device or file not found",
    22: "Device or file not open",
    23: "Input/Output Error",
    24: "Wrong parameter",
    25: "Index out of bounds",
    26: "No error, but the command was not completed, yet. Another return message will follow including a "
    "status code, if the function was completed.",
    27: "Data overrun",
    28: "Range error",
    29: "Axis blocked",
    30: "File already exists",
}


def to_status(code: int) -> Status | int:
    """The :class:`Status` of a known code, the plain int of an unknown one (newer firmware may add codes)."""
    try:
        return Status(code)
    except ValueError:
        return int(code)


def status_name(code: int) -> str:
    """``E_NAME`` or ``"status N"``; never raises."""
    status = to_status(code)
    return status.name if isinstance(status, Status) else f"status {status}"
