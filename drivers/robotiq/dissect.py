"""Robotiq Modbus frames as people read them: the ``grippers.monitor/1`` record of drivers/dissect.py, with
the request block (rACT, rGTO, rPR, ...) and the status block (gSTA, gOBJ, gFLT, gPO, ...) decoded.

The client logs every frame it sends and receives through :func:`log_frame` (the ``grippers.wire`` logger, at
DEBUG: ``-vv``); :class:`ModbusStream` reassembles frames from a byte stream for a monitor. Pure code, no I/O.
"""

from __future__ import annotations

import logging
from typing import Any

from ..dissect import FROM_GRIPPER, TO_GRIPPER, log_record, record, wire_log
from . import modbus
from .modbus import FUNCTIONS, RequestParser, Response, ResponseParser
from .registers import COMMAND_ADDRESS, STATUS_ADDRESS, Command, Status, fault_name

PROTOCOL = "modbus"
URCAP_PROTOCOL = "urcap"


def _command_text(cmd: Command) -> str:
    bits = [
        name for name, on in (("ACT", cmd.act), ("GTO", cmd.gto), ("ATR", cmd.atr), ("ARD", cmd.ard)) if on
    ]
    return f"r{'|r'.join(bits) if bits else '-'} rPR={cmd.position} rSP={cmd.speed} rFR={cmd.force}"


def _status_fields(values: tuple[int, ...]) -> tuple[dict[str, Any], str]:
    st = Status.from_registers(values)
    fields = {
        "gACT": int(st.act),
        "gGTO": int(st.gto),
        "gSTA": st.sta.name,
        "gOBJ": st.obj.name,
        "gFLT": fault_name(st.fault) if st.fault else "none",
        "gPR": st.position_echo,
        "gPO": st.position,
        "gCU": st.current,
    }
    return fields, st.describe()


def request_record(req: modbus.Request, stamp: float | None = None) -> dict[str, Any]:
    name = FUNCTIONS.get(req.function, f"function {req.function}")
    fields: dict[str, Any] = {"address": req.address, "count": req.count}
    text = f"slave {req.slave} {name} 0x{req.address:04X} x{req.count}"
    if req.values:
        fields["write_address"] = req.write_address
        if req.write_address == COMMAND_ADDRESS and len(req.values) == 3:
            cmd = Command.from_registers(req.values)
            fields["command"] = _command_text(cmd)
            text = f"slave {req.slave} {name}: {_command_text(cmd)}"
            if req.function == modbus.READ_WRITE:
                text += f"; read 0x{req.address:04X} x{req.count}"
    return record(
        time=stamp,
        protocol=PROTOCOL,
        direction=TO_GRIPPER,
        node=req.slave,
        command=name,
        fields=fields,
        text=text,
        raw=req.raw.hex(),
    )


def response_record(
    rep: Response, stamp: float | None = None, *, address: int | None = None
) -> dict[str, Any]:
    name = FUNCTIONS.get(rep.function, f"function {rep.function}")
    fields: dict[str, Any] = {}
    status = None
    if rep.exception is not None:
        status = f"exception {rep.exception}"
        text = f"slave {rep.slave} {name}: exception {rep.exception}"
    elif rep.function == modbus.WRITE_MULTIPLE:
        text = f"slave {rep.slave} {name}: 0x{rep.address:04X} x{rep.count} written"
    elif address in (None, STATUS_ADDRESS) and 1 <= len(rep.values) <= 8:
        fields, described = _status_fields(rep.values)
        text = f"slave {rep.slave} {name}: {described}"
    else:
        fields = {"registers": list(rep.values)}
        text = f"slave {rep.slave} {name}: {' '.join(f'{v:04X}' for v in rep.values)}"
    return record(
        time=stamp,
        protocol=PROTOCOL,
        direction=FROM_GRIPPER,
        node=rep.slave,
        command=name,
        fields=fields,
        status=status,
        text=text,
        raw=rep.raw.hex(),
    )


def log_frame(device: str, direction: str, frame: bytes) -> None:
    """One frame to the ``grippers.wire`` logger, decoded (the caller checks DEBUG is on)."""
    if direction == TO_GRIPPER:
        reqs = RequestParser(None).feed(frame)
        recs = [request_record(r) for r in reqs]
    else:
        reps = ResponseParser(None).feed(frame)
        recs = [response_record(r) for r in reps]
    if not recs:
        recs = [
            record(protocol=PROTOCOL, direction=direction, text=f"bytes {frame.hex(' ')}", raw=frame.hex())
        ]
    for rec in recs:
        log_record(device, rec)


def log_urcap(device: str, direction: str, line: bytes) -> None:
    """One URCap request or reply (``SET POS 100 GTO 1``, ``ack``, ``OBJ 3``) to the ``grippers.wire`` logger
    (the caller checks DEBUG is on): the socket's ASCII is already readable, so the text is the line."""
    text = line.decode("ascii", "replace").strip()
    log_record(
        device,
        record(
            protocol=URCAP_PROTOCOL,
            direction=direction,
            command=text.partition(" ")[0] if direction == TO_GRIPPER else None,
            text=text,
            raw=line.hex(),
        ),
    )


def wire_debug() -> bool:
    return wire_log.isEnabledFor(logging.DEBUG)


class ModbusStream:
    """Frames reassembled from the bytes of one direction of the line (a monitor's tap)."""

    def __init__(self, direction: str) -> None:
        self.direction = direction
        self._requests = RequestParser(None)
        self._responses = ResponseParser(None)

    def feed(self, data: bytes, stamp: float | None = None) -> list[dict[str, Any]]:
        if self.direction == TO_GRIPPER:
            return [request_record(r, stamp) for r in self._requests.feed(data)]
        return [response_record(r, stamp) for r in self._responses.feed(data)]


class ModbusDissector:
    """Both directions of a Modbus RTU line (a monitor's proxy or a byte capture): requests to the gripper,
    responses from it, each reassembled by its own parser (the ``feed(direction, data, stamp)`` of a byte
    stream dissector, as ``grippers monitor`` calls it)."""

    protocol = PROTOCOL

    def __init__(self) -> None:
        self._streams = {TO_GRIPPER: ModbusStream(TO_GRIPPER), FROM_GRIPPER: ModbusStream(FROM_GRIPPER)}

    def feed(self, direction: str, data: bytes, stamp: float | None) -> list[dict[str, Any]]:
        stream = self._streams.get(direction)
        if stream is None:  # a capture without direction marks: a request parser reads what a client sent
            stream = self._streams[TO_GRIPPER]
        return stream.feed(data, stamp)

    def flush(self) -> list[dict[str, Any]]:
        return []
