"""The Robotiq device client: the kit's :class:`~grippers.drivers.modbus_client.ModbusClient` (RTU over an
RS-485 line, or raw RTU over TCP from a UR robot's tool-communication forwarder) with the gripper's register
map: the status block read with function 03 or 04, the request block written with 16, or both with 23.

Everything about the exchange (the deadline, a late reply dropped, t3.5, exception replies as typed
:class:`~grippers.CommandFailed` errors, the hint when another slave id answers) is the kit's; this module
adds the register map, Robotiq's defaults and the decoded wire log (``-vv``).
"""

from __future__ import annotations

from typing import Any, Self

from ..links import ByteLink, TraceFn
from ..modbus import READ_HOLDING, READ_INPUT
from ..modbus_client import ModbusClient
from .dissect import log_frame, wire_debug
from .registers import (
    BAUDRATE,
    BLOCK_REGISTERS,
    COMMAND_ADDRESS,
    DEFAULT_SLAVE,
    FORWARDER_PORT,
    STATUS_ADDRESS,
    Command,
    Status,
)

__all__ = ["ByteLink", "RobotiqClient", "TraceFn"]


class RobotiqClient(ModbusClient):
    """Register exchanges with one gripper (slave id ``slave``, 9 by default).

    ``read_function`` is how the status is read: 03 (the manuals' and the SDK's), or 04. ``inter_frame_s`` is
    the silence kept before a request after the last byte received (t3.5 on a serial line; 0 over TCP).
    """

    def __init__(
        self,
        link: ByteLink,
        *,
        device: str,
        slave: int = DEFAULT_SLAVE,
        timeout: float = 0.5,
        read_function: int = READ_HOLDING,
        inter_frame_s: float = 0.0,
        framing: str = "rtu",
        trace: TraceFn | None = None,
    ) -> None:
        if read_function not in (READ_HOLDING, READ_INPUT):
            raise ValueError(f"read_function must be 3 or 4, not {read_function!r}")
        self.read_function = read_function
        super().__init__(
            link,
            slave=slave,
            device=device,
            timeout=timeout,
            framing=framing,
            inter_frame_s=inter_frame_s,
            frame_log=self._log_frame,
            trace=trace,
        )

    def _log_frame(self, direction: str, frame: bytes) -> None:
        if wire_debug():
            log_frame(self.device, direction, frame)

    @classmethod
    def serial(cls, port: str, *, baudrate: int = BAUDRATE, **kw: Any) -> Self:
        return super().serial(port, baudrate=baudrate, **kw)

    @classmethod
    def tcp(cls, host: str, port: int = FORWARDER_PORT, *, framing: str = "rtu", **kw: Any) -> Self:
        """Raw RTU over TCP (a forwarder), or ``framing="tcp"`` behind a Modbus TCP gateway."""
        return super().tcp(host, port, framing=framing, **kw)

    def read_status(self, *, command: str = "status") -> Status:
        values = self.read_registers(
            STATUS_ADDRESS, BLOCK_REGISTERS, function=self.read_function, command=command
        )
        return Status.from_registers(values)

    def write_command(self, cmd: Command, *, command: str = "command") -> None:
        self.write_registers(COMMAND_ADDRESS, cmd.registers(), command=command)

    def write_and_read(self, cmd: Command, *, command: str = "command") -> Status:
        """FC 23: the command written and the status read in one exchange (the SDK's cycle)."""
        values = self.read_write_registers(
            STATUS_ADDRESS, BLOCK_REGISTERS, COMMAND_ADDRESS, cmd.registers(), command=command
        )
        return Status.from_registers(values)
