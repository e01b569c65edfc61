"""Frames and packets as people read them: the one decoded form shared by ``grippers monitor`` and the
``grippers.wire`` logger (every frame or packet a client sends or receives, at DEBUG).

A record is a plain dict (time, protocol, direction, id, node, command, fields, status, text, raw), the
``grippers.monitor/1`` document of docs/cli.md; :func:`render_line` is its one-line text form. The family
dissectors beside the drivers fill it (:mod:`.wsg.dissect` reassembles WSG packets from bytes,
:mod:`.stepfoc.dissect` reads STEPFOC CAN frames and UART lines); :class:`CanDecoder` chooses between them
for a bus that carries both. Pure code, no I/O; the drivers import it, never ``grippers``.
"""

from __future__ import annotations

import dataclasses
import enum
import logging
from collections.abc import Iterator
from typing import Any

from .captures import FROM_DEVICE as FROM_GRIPPER
from .captures import TO_DEVICE as TO_GRIPPER

__all__ = [
    "FROM_GRIPPER",
    "TO_GRIPPER",
    "WIRE_LOGGER",
    "CanDecoder",
    "field_value",
    "log_record",
    "record",
    "render_line",
]

# Every frame or packet on the wire, at DEBUG, in render_line's form (docs/logging.md).
WIRE_LOGGER = "grippers.wire"
wire_log = logging.getLogger(WIRE_LOGGER)


def field_value(value: Any) -> Any:
    """A decoded field as plain JSON: flags as lists of names, enums by name, records as objects."""
    if isinstance(value, enum.IntFlag):
        return [m.name for m in type(value) if m.name and m in value]
    if isinstance(value, enum.Enum):
        return value.name
    if isinstance(value, float):
        return round(value, 6)
    if isinstance(value, bytes | bytearray):
        return bytes(value).hex()
    if type(value).__name__ == "FirmwareVersion":  # has its own major.minor1.minor2 form
        return str(value)
    if dataclasses.is_dataclass(value) and not isinstance(value, type):
        return {f.name: field_value(getattr(value, f.name)) for f in dataclasses.fields(value)}
    if isinstance(value, dict):
        return {str(k): field_value(v) for k, v in value.items()}
    if isinstance(value, list | tuple):
        return [field_value(v) for v in value]
    return value


def record(**fields: Any) -> dict[str, Any]:
    base: dict[str, Any] = {
        "time": None,
        "protocol": "wsg",
        "direction": "?",
        "id": None,
        "node": None,
        "command": None,
        "fields": {},
        "status": None,
        "text": "",
        "raw": None,
    }
    base.update(fields)
    return base


def render_line(rec: dict[str, Any], *, with_time: bool = True) -> str:
    """time, arrow, protocol, then the drivers' own one-line description (the CAN id for STEPFOC frames).

    ``with_time=False`` leaves the time column out: a log line carries its own time stamp.
    """
    arrow = {TO_GRIPPER: "->", FROM_GRIPPER: "<-"}.get(rec["direction"], "??")
    text = rec["text"]
    if rec["protocol"] == "wsg":
        text = text.removeprefix("-> ").removeprefix("<- ")  # the arrow column says it already
    elif rec["id"] is not None:  # CAN frames; UART lines have no id
        text = f"{rec['id']}  {text}"
    line = f"{arrow}  {rec['protocol']:<7}  {text}".rstrip()
    if not with_time:
        return line
    stamp = "-" if rec["time"] is None else f"{rec['time']:.6f}"
    return f"{stamp:>17}  {line}"


def log_record(device: str, rec: dict[str, Any]) -> None:
    """One record to the ``grippers.wire`` logger (the caller checked that DEBUG is on)."""
    wire_log.debug("%s  %s", device, render_line(rec, with_time=False))


class CanDecoder:
    """Decodes CAN frames: STEPFOC frames by the drivers' table, WSG packets reassembled from their ids."""

    def __init__(self, protocol: str, wsg_id: int) -> None:
        self.protocol = protocol
        self.wsg_id = wsg_id
        self._wsg: Any = None  # a wsg.dissect.WsgStream, made on the first WSG frame

    def _wsg_stream(self) -> Any:
        if self._wsg is None:
            from .wsg.dissect import WsgStream

            self._wsg = WsgStream()
        return self._wsg

    def _is_wsg(self, arbitration_id: int, data: bytes, direction: str) -> bool:
        if self.protocol != "auto":
            return self.protocol == "wsg"
        if arbitration_id not in (self.wsg_id, self.wsg_id + 1):
            return False
        # These ids are also a STEPFOC node's frames (0x000 is node 0's E-stop, which has no data): a frame is
        # WSG when it starts a packet or continues one (docs/protocols.md §1 CAN: 8-byte chunks of a packet).
        return data.startswith(b"\xaa") or (self._wsg is not None and self._wsg.busy(direction))

    def decode(
        self,
        arbitration_id: int,
        data: bytes,
        is_remote: bool,
        stamp: float | None,
        *,
        is_extended: bool = False,
        is_fd: bool = False,
        is_error: bool = False,
    ) -> list[dict]:
        """One frame to records. Never raises: a frame neither protocol can carry (an error frame, an
        extended or CAN FD frame, an id above 0x7FF) is shown as what it is, and a decoding failure is a
        record with the reason, so a live monitor outlives anything the bus carries."""
        wide = is_extended or is_error or arbitration_id > 0x7FF
        ident = f"{arbitration_id:08X}" if wide else f"{arbitration_id:03X}"
        other = None
        if is_error:
            other = "error frame", f"CAN error frame (class 0x{arbitration_id:X}, data {data.hex() or '-'})"
        elif is_extended or arbitration_id > 0x7FF:
            # STEPFOC and the WSG use 11-bit identifiers only (docs/protocols.md §1 CAN, §2 CAN).
            other = "extended frame", f"extended (29-bit) id, not a WSG or STEPFOC frame: {data.hex() or '-'}"
        elif is_fd:
            other = "fd frame", f"CAN FD frame ({len(data)} bytes), not a WSG or STEPFOC frame: {data.hex()}"
        if other is not None:
            return [
                record(
                    time=stamp,
                    protocol="can",
                    id=ident,
                    status=other[0],
                    fields={"bytes": len(data)},
                    text=other[1],
                    raw="R" if is_remote else data.hex(),
                )
            ]
        try:
            return self._decode(arbitration_id, data, is_remote, stamp)
        except Exception as exc:  # a bug or a table gap must not end the monitor: show the frame and why
            return [
                record(
                    time=stamp,
                    protocol="can",
                    id=ident,
                    status="error",
                    fields={"error": str(exc)},
                    text=f"undecodable frame ({type(exc).__name__}: {exc}): {data.hex() or '-'}",
                    raw="R" if is_remote else data.hex(),
                )
            ]

    def _decode(self, arbitration_id: int, data: bytes, is_remote: bool, stamp: float | None) -> list[dict]:
        direction = FROM_GRIPPER if arbitration_id == self.wsg_id + 1 else TO_GRIPPER
        if not is_remote and self._is_wsg(arbitration_id, data, direction):
            return list(self._wsg_stream().feed(direction, data, stamp))
        from .stepfoc.dissect import can_frame_record

        return [can_frame_record(arbitration_id, data, is_remote, stamp)]

    def flush(self) -> Iterator[dict[str, Any]]:
        if self._wsg is not None:
            yield from self._wsg.flush()
