"""A SCHUNK unit's Modbus RTU frames as people read them (``grippers monitor FILE --protocol schunk``): the
``grippers.monitor/1`` record of drivers/dissect.py, the instance named (``0x0040 plc_sync_input``) and the
process data decoded (status bits, position, the error code; the control word's command bits and targets).
Pure code, no I/O; the frames are the generic Modbus RTU codec's (:mod:`grippers.drivers.modbus`)."""

from __future__ import annotations

from typing import Any

from .. import modbus
from ..dissect import FROM_GRIPPER, TO_GRIPPER, log_record, record
from .protocol import (
    PARAMETERS,
    PLC_INPUT,
    PLC_OUTPUT,
    CodecError,
    ControlWord,
    Fieldbus,
    ProcessInput,
    decode,
    error_name,
)
from .rtu import bytes_of

PROTOCOL = "schunk-modbus"


def _name(inst: int) -> str:
    p = PARAMETERS.get(inst)
    return f"0x{inst:04X} {p.name}" if p is not None else f"0x{inst:04X}"


def _flags(value: Any) -> str:
    return "|".join(f.name or "" for f in type(value) if f in value and f.value) or "-"


def input_text(data: bytes, fieldbus: Fieldbus = Fieldbus.MODBUS) -> str:
    """0x0040 as a line: the status bits, the position and the error."""
    try:
        pi = ProcessInput.decode(data, fieldbus)
    except CodecError:
        return data.hex(" ")
    error = f" {error_name(pi.error)}" if pi.error else ""
    return f"{_flags(pi.status)} at {pi.position_um} um{error}"


def output_text(data: bytes, fieldbus: Fieldbus = Fieldbus.MODBUS) -> str:
    """0x0048 as a line: the command bits and the targets."""
    try:
        word = ControlWord.decode(data, fieldbus)
    except CodecError:
        return data.hex(" ")
    fast_stop = "" if word.control & 1 else " FAST STOP (bit 0 low)"
    return (
        f"{_flags(word.control)} target {word.position_um} um at {word.speed_um_s} um/s, "
        f"force {word.force_percent} %{fast_stop}"
    )


class SchunkDissector:
    """Both directions of the line (a capture or stdin): requests to the unit, replies from it. A read's
    reply is decoded by the instance of the request before it."""

    protocol = PROTOCOL

    def __init__(self) -> None:
        self._requests = modbus.RequestParser(None)
        self._responses = modbus.ResponseParser(None)
        self._last_read: int | None = None

    def feed(self, direction: str, data: bytes, stamp: float | None) -> list[dict[str, Any]]:
        if direction == FROM_GRIPPER:
            return [self._response(r, stamp) for r in self._responses.feed(data)]
        return [self._request(r, stamp) for r in self._requests.feed(data)]

    def flush(self) -> list[dict[str, Any]]:
        return []

    def _request(self, req: modbus.Request, stamp: float | None) -> dict[str, Any]:
        inst = req.address + 1
        if req.function == modbus.WRITE_MULTIPLE:
            data = bytes_of(req.values)
            detail = output_text(data) if inst == PLC_OUTPUT else data.hex(" ")
            text = f"id {req.slave} write {_name(inst)}: {detail}"
        else:
            self._last_read = inst
            text = f"id {req.slave} read {_name(inst)} x{req.count}"
        return record(
            time=stamp,
            protocol=PROTOCOL,
            direction=TO_GRIPPER,
            node=req.slave,
            command=modbus.FUNCTIONS.get(req.function, f"function {req.function}"),
            fields={"instance": f"0x{inst:04X}", "count": req.count},
            text=text,
            raw=req.raw.hex(),
        )

    def _response(self, rep: modbus.Response, stamp: float | None) -> dict[str, Any]:
        status = None
        if rep.exception is not None:
            status = f"exception {rep.exception}"
            text = f"id {rep.slave}: Modbus exception {rep.exception}"
        elif rep.function == modbus.WRITE_MULTIPLE:
            text = f"id {rep.slave}: {_name(rep.address + 1)} written"
        else:
            data, inst = bytes_of(rep.values), self._last_read
            detail = input_text(data) if inst == PLC_INPUT else data.hex(" ")
            text = f"id {rep.slave}: {_name(inst) if inst is not None else 'read'} = {detail}"
        return record(
            time=stamp,
            protocol=PROTOCOL,
            direction=FROM_GRIPPER,
            node=rep.slave,
            command=modbus.FUNCTIONS.get(rep.function, f"function {rep.function}"),
            status=status,
            text=text,
            raw=rep.raw.hex(),
        )


def log_exchange(
    device: str, transport: str, inst: int, data: bytes, fieldbus: Fieldbus, *, write: bool
) -> None:
    """One parameter read or write to the ``grippers.wire`` logger (``-vv``), decoded: what went to the unit
    and what came back, on either transport (the caller checks that DEBUG is on)."""
    if inst == PLC_INPUT:
        detail = input_text(data, fieldbus)
    elif inst == PLC_OUTPUT:
        detail = output_text(data, fieldbus)
    else:
        try:
            detail = repr(decode(inst, data, fieldbus))
        except CodecError:
            detail = data.hex(" ")
    if write:
        rec = record(
            protocol=f"schunk-{transport}", direction=TO_GRIPPER, text=f"write {_name(inst)}: {detail}"
        )
    else:
        rec = record(protocol=f"schunk-{transport}", direction=FROM_GRIPPER, text=f"{_name(inst)} = {detail}")
    log_record(device, rec)
