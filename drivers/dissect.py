"""Frames and packets as people read them: the one decoded form shared by ``grippers monitor`` and the
``grippers.wire`` logger (every frame or packet a client sends or receives, at DEBUG).

A record is a plain dict (time, protocol, direction, id, node, command, fields, status, text, raw), the
``grippers.monitor/1`` document of docs/cli.md; :func:`render_line` is its one-line text form. The family
dissectors beside each family's driver fill it, and this module knows none of them (issue 28 §2): a family
that shows its text in its own way registers that form (:func:`register_text_form`), and
:class:`CanDecoder` asks the CAN dissectors it is given, in order, which of them reads a frame (a bus may
carry several families). The backends hand their dissectors to ``grippers monitor`` (their ``dissector()``
hook). Pure code, no I/O; the drivers import it, never ``grippers``.
"""

from __future__ import annotations

import dataclasses
import enum
import logging
from collections.abc import Callable, Iterator, Sequence
from typing import Any, Protocol

from .captures import FROM_DEVICE as FROM_GRIPPER
from .captures import TO_DEVICE as TO_GRIPPER

__all__ = [
    "FROM_GRIPPER",
    "TO_GRIPPER",
    "WIRE_LOGGER",
    "CanDecoder",
    "CanDissector",
    "field_value",
    "log_record",
    "record",
    "register_text_form",
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
    """One record of the ``grippers.monitor/1`` document (docs/cli.md): the keys below, given ones replaced.
    ``raw`` is the frame as hex text (``data.hex()``, ``"R"`` for a CAN remote frame), as the JSON carries
    it, in every family's dissector: bytes are refused (a TypeError), so no dissector writes another form."""
    if isinstance(fields.get("raw"), bytes | bytearray | memoryview):
        raise TypeError("a monitor record's raw is hex text: pass data.hex(), not the bytes")
    base: dict[str, Any] = {
        "time": None,
        "protocol": None,  # the family dissector's own name ("can" for a frame no family reads)
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


# protocol -> the one-line text of its records, for a family whose text is not "ID  description"
_text_forms: dict[str, Callable[[dict[str, Any]], str]] = {}


def register_text_form(protocol: str, form: Callable[[dict[str, Any]], str]) -> None:
    """A family's own text column (its dissector module registers it when imported, before any record)."""
    _text_forms[protocol] = form


def render_line(rec: dict[str, Any], *, with_time: bool = True) -> str:
    """time, arrow, protocol, then the drivers' own one-line description (the frame's id first, unless the
    family registered its own form).

    ``with_time=False`` leaves the time column out: a log line carries its own time stamp.
    """
    arrow = {TO_GRIPPER: "->", FROM_GRIPPER: "<-"}.get(rec["direction"], "??")
    form = _text_forms.get(rec["protocol"])
    if form is not None:
        text = form(rec)
    elif rec["id"] is not None:  # CAN frames and the like; UART lines have no id
        text = f"{rec['id']}  {rec['text']}"
    else:
        text = rec["text"]
    line = f"{arrow}  {rec['protocol']:<7}  {text}".rstrip()
    if not with_time:
        return line
    stamp = "-" if rec["time"] is None else f"{rec['time']:.6f}"
    return f"{stamp:>17}  {line}"


def log_record(device: str, rec: dict[str, Any]) -> None:
    """One record to the ``grippers.wire`` logger (the caller checked that DEBUG is on)."""
    wire_log.debug("%s  %s", device, render_line(rec, with_time=False))


class CanDissector(Protocol):
    """One family's reading of CAN frames (its driver's ``dissect`` module makes it)."""

    protocol: str
    catch_all: bool  # reads any 11-bit frame (asked last), or only its own (asked first)

    def claims(self, arbitration_id: int, data: bytes, is_remote: bool) -> bool: ...

    def decode(
        self, arbitration_id: int, data: bytes, is_remote: bool, stamp: float | None
    ) -> list[dict]: ...

    def flush(self) -> Iterator[dict[str, Any]]: ...


class CanDecoder:
    """Decodes CAN frames with the families' dissectors: the first that claims a frame reads it; those that
    read only their own ids are asked before one that reads anything."""

    def __init__(self, dissectors: Sequence[CanDissector]) -> None:
        self.dissectors = sorted(dissectors, key=lambda d: d.catch_all)  # stable: the given order otherwise

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
            # The families' CAN protocols use 11-bit identifiers only (docs/protocols.md §1 CAN, §2 CAN).
            other = "extended frame", f"extended (29-bit) id, not a gripper's frame: {data.hex() or '-'}"
        elif is_fd:
            other = "fd frame", f"CAN FD frame ({len(data)} bytes), not a gripper's frame: {data.hex()}"
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
        for dissector in self.dissectors:
            if dissector.claims(arbitration_id, data, is_remote):
                return dissector.decode(arbitration_id, data, is_remote, stamp)
        return [
            record(
                time=stamp,
                protocol="can",
                id=f"{arbitration_id:03X}",
                status="unclaimed",
                fields={"bytes": len(data)},
                text=f"no dissector reads this frame: {data.hex() or '-'}",
                raw="R" if is_remote else data.hex(),
            )
        ]

    def flush(self) -> Iterator[dict[str, Any]]:
        for dissector in self.dissectors:
            yield from dissector.flush()
