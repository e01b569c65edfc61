"""STEPFOC frames and UART lines as records of :mod:`grippers.drivers.dissect` (the form ``grippers monitor``
prints and the ``grippers.wire`` logger writes), read with the driver's own frame table."""

from __future__ import annotations

import dataclasses
import logging
from collections.abc import Iterator
from typing import Any

from ..dissect import FROM_GRIPPER, TO_GRIPPER, field_value, log_record, record, wire_log
from . import can_protocol as cp


def can_frame_record(
    arbitration_id: int, data: bytes, is_remote: bool, stamp: float | None
) -> dict[str, Any]:
    """One STEPFOC CAN frame; a frame the table cannot read is a record saying why, never an exception."""
    node, command, _error = cp.unpack_id(arbitration_id)
    base = {
        "time": stamp,
        "protocol": "stepfoc",
        "id": f"{arbitration_id:03X}",
        "node": node,
        "raw": "R" if is_remote else data.hex(),
        "text": cp.describe(arbitration_id, data, is_remote),
    }
    try:
        msg = cp.decode_frame(arbitration_id, data, is_remote)
    except Exception as exc:  # wrong length or a remote frame where data belongs: shown with why
        spec = cp.COMMANDS.get(command)
        return record(
            **base,
            direction="?",
            command=spec.name if spec else f"command_{command}",
            status="error",
            fields={"error": str(exc)},
        )
    if msg.value is None:
        fields: dict[str, Any] = {}
    elif dataclasses.is_dataclass(msg.value):
        fields = field_value(msg.value)
    else:
        fields = {msg.name: field_value(msg.value)}
    return record(
        **base,
        direction=FROM_GRIPPER if msg.from_node else TO_GRIPPER,
        command=msg.name,
        fields=fields,
        status="error" if msg.error else None,
    )


class StepfocCanDissector:
    """STEPFOC frames for :class:`grippers.drivers.dissect.CanDecoder`: any 11-bit frame is some node's
    (the id holds the node and the command), so it reads what no family with its own ids claimed."""

    protocol = "stepfoc"
    catch_all = True

    def claims(self, arbitration_id: int, data: bytes, is_remote: bool) -> bool:
        return True

    def decode(self, arbitration_id: int, data: bytes, is_remote: bool, stamp: float | None) -> list[dict]:
        return [can_frame_record(arbitration_id, data, is_remote, stamp)]

    def flush(self) -> Iterator[dict[str, Any]]:
        return iter(())


def uart_line_record(direction: str, text: str, stamp: float | None) -> dict[str, Any]:
    """One line of the UART text protocol (a command sent or a line the firmware printed), as it is."""
    return record(
        time=stamp, protocol="stepfoc", direction=direction, text=text.strip(), raw=text.encode().hex()
    )


def log_can_frame(
    device: str, arbitration_id: int, data: bytes | bytearray, is_remote: bool, stamp: float | None
) -> None:
    """A frame sent or received, to the ``grippers.wire`` logger at DEBUG; costs one level check when off."""
    if wire_log.isEnabledFor(logging.DEBUG):
        rec = can_frame_record(arbitration_id, bytes(data), is_remote, stamp)
        log_record(device, rec)


def log_uart_line(device: str, sent: bool, text: str, stamp: float | None) -> None:
    """A UART line written or read, to the ``grippers.wire`` logger at DEBUG."""
    if wire_log.isEnabledFor(logging.DEBUG):
        rec = uart_line_record(TO_GRIPPER if sent else FROM_GRIPPER, text, stamp)
        log_record(device, rec)
