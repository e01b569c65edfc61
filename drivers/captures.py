"""Readers for recorded traffic: candump logs for CAN, hex dumps and raw byte files for the WSG protocol.

Pure text/bytes in, records out (no I/O beyond what the caller hands in), so each format's quirks are testable
on strings. Every malformed line is reported with its line number instead of being skipped silently: a capture
that half-decodes would mislead whoever reads the monitor's output.
"""

from __future__ import annotations

import re
from collections.abc import Iterable, Iterator
from dataclasses import dataclass

# Direction words. WSG captures carry direction per chunk; STEPFOC frames carry it in the command id.
TO_DEVICE = "host->gripper"
FROM_DEVICE = "gripper->host"
UNKNOWN_DIRECTION = "?"


CAN_ERR_FLAG = 0x20000000  # linux/can.h: the error-frame flag in a can_id
CAN_MAX_DATA = 8  # linux/can.h CAN_MAX_DLEN: a classic frame's data
CAN_FD_MAX_DATA = 64  # linux/can.h CANFD_MAX_DLEN


class CaptureError(ValueError):
    """A capture that does not parse; names the line."""


@dataclass(frozen=True)
class CanRecord:
    """One CAN frame of a capture."""

    timestamp: float | None
    channel: str | None
    arbitration_id: int
    data: bytes
    is_remote: bool
    is_extended: bool
    line: int
    is_fd: bool = False
    is_error: bool = False


@dataclass(frozen=True)
class ByteChunk:
    """A run of bytes from a byte-stream capture, in one direction."""

    timestamp: float | None
    direction: str
    data: bytes
    line: int


# --- candump -----------------------------------------------------------------------------------------------
# Formats from can-utils' candump: the log format (-l/-L) "(1436509052.249713) vcan0 044#2A366C2BBA", with
# "123#R" or "123#R4" for remote frames and "##" for CAN FD; and the screen format
# "  can0  123   [4]  DE AD BE EF", optionally after "(timestamp)" (-t) and with "TX - -"/"RX - -" (-x).
_LOG_RE = re.compile(
    r"^\((?P<ts>[0-9]+(?:\.[0-9]+)?)\)\s+(?P<chan>\S+)\s+(?P<id>[0-9A-Fa-f]{1,8})(?P<sep>##?)(?P<rest>\S*)"
    r"(?:\s+(?P<dir>[TR]))?\s*$"
)
_SCREEN_RE = re.compile(
    r"^(?:\((?P<ts>[0-9]+(?:\.[0-9]+)?)\)\s+)?(?P<chan>\S+)\s+(?:(?P<dir>[TR]X)\s+\S+\s+\S+\s+)?"
    r"(?P<id>[0-9A-Fa-f]{1,8})\s+\[(?P<dlc>[0-9]{1,2})\]\s*(?P<rest>.*?)\s*$"
)


def parse_candump(lines: Iterable[str]) -> Iterator[CanRecord]:
    """Frames of a candump capture (log or screen format; blank lines and ``#`` comments skipped)."""
    for number, raw in enumerate(lines, start=1):
        text = raw.strip()
        if not text or text.startswith("#"):
            continue
        record = _parse_log_line(text, number) or _parse_screen_line(text, number)
        if record is None:
            raise CaptureError(f"line {number}: not a candump line: {text[:60]!r}")
        yield record


def _parse_log_line(text: str, number: int) -> CanRecord | None:
    m = _LOG_RE.match(text)
    if not m:
        return None
    ident = m["id"]
    rest = m["rest"]
    if m["sep"] == "##":
        rest = rest[1:]  # CAN FD: one flags nibble precedes the data
    remote = rest[:1] in ("R", "r")
    data = b""
    if not remote:
        if len(rest) % 2:
            raise CaptureError(f"line {number}: odd number of hex digits in {rest!r}")
        try:
            data = bytes.fromhex(rest)
        except ValueError:
            raise CaptureError(f"line {number}: bad data {rest!r}") from None
    fd = m["sep"] == "##"
    if len(data) > (CAN_FD_MAX_DATA if fd else CAN_MAX_DATA):
        kind = "CAN FD frame" if fd else "CAN frame"
        raise CaptureError(
            f"line {number}: {len(data)} data bytes; a {kind} carries at most "
            f"{CAN_FD_MAX_DATA if fd else CAN_MAX_DATA}"
        )
    value = int(ident, 16)
    extended = len(ident) > 3
    # can-utils' lib.c prints an error frame's id with CAN_ERR_FLAG (0x20000000, linux/can.h) set.
    error = extended and bool(value & CAN_ERR_FLAG)
    return CanRecord(
        timestamp=float(m["ts"]),
        channel=m["chan"],
        arbitration_id=value & ~CAN_ERR_FLAG if error else value,
        data=data,
        is_remote=remote,
        is_extended=extended and not error,
        line=number,
        is_fd=m["sep"] == "##",
        is_error=error,
    )


def _parse_screen_line(text: str, number: int) -> CanRecord | None:
    m = _SCREEN_RE.match(text)
    if not m:
        return None
    rest = m["rest"]
    remote = "remote request" in rest
    data = b""
    if not remote:
        try:
            data = bytes.fromhex(rest.split("'")[0])
        except ValueError:
            raise CaptureError(f"line {number}: bad data {rest!r}") from None
        if len(data) != int(m["dlc"]):
            raise CaptureError(f"line {number}: [{m['dlc']}] but {len(data)} data bytes")
        if len(data) > CAN_FD_MAX_DATA:
            raise CaptureError(f"line {number}: {len(data)} data bytes; a CAN frame carries at most 64")
    return CanRecord(
        timestamp=float(m["ts"]) if m["ts"] else None,
        channel=m["chan"],
        arbitration_id=int(m["id"], 16),
        data=data,
        is_remote=remote,
        is_extended=len(m["id"]) > 3,
        line=number,
    )


def format_candump(
    timestamp: float,
    channel: str,
    arbitration_id: int,
    data: bytes,
    *,
    is_remote: bool = False,
    is_extended: bool = False,
    is_fd: bool = False,
    is_error: bool = False,
) -> str:
    """One frame as a candump log line (``candump -L``), the form :func:`parse_candump` and can-utils'
    canplayer read back: 3 hex digits for a standard id, 8 for an extended one or an error frame."""
    if is_error:
        ident = f"{(arbitration_id | CAN_ERR_FLAG):08X}"
    elif is_extended or arbitration_id > 0x7FF:
        ident = f"{arbitration_id:08X}"
    else:
        ident = f"{arbitration_id:03X}"
    if is_remote:
        body = "#R" + (str(len(data)) if data else "")
    elif is_fd:
        body = "##0" + data.hex().upper()
    else:
        body = "#" + data.hex().upper()
    return f"({timestamp:.6f}) {channel} {ident}{body}"


# --- hex dumps ---------------------------------------------------------------------------------------------
# Accepted: plain hex ("AA AA AA 01 00 00 E8 10", "aaaaaa010000e810", "0xAA, 0xAA"), `xxd` lines
# ("00000000: aaaa aa01 0000 e810  ........") and `hexdump -C` lines ("00000000  aa aa aa 01 ... |....|").
# Each line may start with "(timestamp)" and a direction: ">", "->", "tx", "host->gripper" for bytes sent to
# the gripper; "<", "<-", "rx", "gripper->host" for bytes from it.
_DIRECTIONS = {
    ">": TO_DEVICE,
    "->": TO_DEVICE,
    "tx": TO_DEVICE,
    "host->gripper": TO_DEVICE,
    "out": TO_DEVICE,
    "<": FROM_DEVICE,
    "<-": FROM_DEVICE,
    "rx": FROM_DEVICE,
    "gripper->host": FROM_DEVICE,
    "in": FROM_DEVICE,
}
_TS_RE = re.compile(r"^\((?P<ts>[0-9]+(?:\.[0-9]+)?)\)\s*")
_XXD_RE = re.compile(r"^[0-9A-Fa-f]{6,16}:\s")
_HEXDUMP_C_RE = re.compile(r"^[0-9A-Fa-f]{8}\s\s")
_HEX_RE = re.compile(r"^(?:[0-9A-Fa-f]{2})+$")


def parse_hex_dump(lines: Iterable[str], default_direction: str = UNKNOWN_DIRECTION) -> Iterator[ByteChunk]:
    """Byte chunks of a hex dump, one per line; raises :class:`CaptureError` naming a bad line."""
    for number, raw in enumerate(lines, start=1):
        text = raw.strip()
        if not text or text.startswith("#"):
            continue
        timestamp = None
        m = _TS_RE.match(text)
        if m:
            timestamp = float(m["ts"])
            text = text[m.end() :]
        direction = default_direction
        head, _, tail = text.partition(" ")
        if head.lower() in _DIRECTIONS:
            direction = _DIRECTIONS[head.lower()]
            text = tail.strip()
        elif text[:1] and text[:1] in "<>" and text[1:2] != "-":
            direction = _DIRECTIONS[text[0]]
            text = text[1:].strip()
        data = _hex_bytes(text, number)
        if data:
            yield ByteChunk(timestamp=timestamp, direction=direction, data=data, line=number)


def _hex_bytes(text: str, number: int) -> bytes:
    if _XXD_RE.match(text):
        body = text.split(":", 1)[1]
        body = re.split(r"\s{2,}", body.strip(), maxsplit=1)[0]  # drop the ASCII column
    elif _HEXDUMP_C_RE.match(text):
        body = text[8:].split("|", 1)[0]
    else:
        body = text
    digits = re.sub(r"0[xX]", "", body)
    digits = re.sub(r"[\s,:;-]", "", digits)
    if not digits:
        return b""
    if not _HEX_RE.match(digits):
        raise CaptureError(f"line {number}: not hex bytes: {text[:60]!r}")
    return bytes.fromhex(digits)


def format_hex_line(timestamp: float, direction: str, data: bytes) -> str:
    """A chunk of a byte stream as a hex-dump line with its time and direction, which
    :func:`parse_hex_dump` reads back: ``(1700000000.123456) > AA AA AA 01 00 00 E8 10``."""
    arrow = {TO_DEVICE: ">", FROM_DEVICE: "<"}.get(direction, "")
    return f"({timestamp:.6f}) {arrow} {data.hex(' ').upper()}".replace("  ", " ")


def looks_like_text(blob: bytes) -> bool:
    """Whether a capture file is a text dump (hex or candump) rather than raw bytes."""
    if not blob:
        return True
    try:
        text = blob.decode("ascii")
    except UnicodeDecodeError:
        return False
    return all(ch.isprintable() or ch in "\r\n\t" for ch in text)


def sniff_format(blob: bytes) -> str:
    """'candump', 'hex' or 'raw' for a capture whose format the user did not name."""
    if not looks_like_text(blob):
        return "raw"
    for line in blob.decode("ascii").splitlines():
        text = line.strip()
        if not text or text.startswith("#"):
            continue
        if _LOG_RE.match(text) or _SCREEN_RE.match(text):
            return "candump"
        try:
            next(parse_hex_dump([text]), None)
        except CaptureError:
            return "raw"
        return "hex"
    return "hex"
