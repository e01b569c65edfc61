"""The Robotiq device client: register exchanges over an RS-485 line (pyserial) or raw RTU over TCP (a UR
robot's tool-communication forwarder), thread-safe, every wait bounded.

The bytes move over a link of the backend kit (:mod:`grippers.drivers.links`: :class:`SerialLink`,
:class:`TcpLink`), which bounds every read and keeps the lost flag; this module adds Modbus's rules. Modbus is
strictly request/response with one master, so no reader thread is needed: an exchange writes a request and
reads until the parser returns the one answer it expects, under a lock that serialises callers (a state
stream and a motion wait share one line). Errors name the device, the command and the cause:
:class:`GripperTimeout` (no answer), :class:`ConnectionLost` (the link failed), :class:`CommandFailed`
(a Modbus exception), all from drivers/errors.py.
"""

from __future__ import annotations

import threading
import time
from typing import Any

from ..dissect import FROM_GRIPPER, TO_GRIPPER
from ..errors import CommandFailed, ConnectionLost, GripperTimeout
from ..links import ByteLink, SerialLink, TcpLink, TraceFn
from . import modbus
from .dissect import log_frame, wire_debug
from .modbus import READ_HOLDING, READ_INPUT, READ_WRITE, ExceptionCode, ResponseParser
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

# How long after a timeout the input is dropped before each request: a late reply seen in the field comes
# within a few timeouts (issue 43: 0.6 s against 0.3 s); past this window no read is spent on it.
LATE_WINDOW_TIMEOUTS = 10
LATE_WINDOW_S = 2.0


class RobotiqClient:
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
        trace: TraceFn | None = None,
    ) -> None:
        if read_function not in (READ_HOLDING, READ_INPUT):
            raise ValueError(f"read_function must be 3 or 4, not {read_function!r}")
        self.link = link
        self.device = device
        self.slave = slave
        self.timeout = timeout
        self.read_function = read_function
        self.inter_frame_s = inter_frame_s
        if trace is not None:
            link.trace = trace
        self._parser = ResponseParser(slave)
        self._lock = threading.Lock()
        self.exchanges = 0
        self._late_until = 0.0  # an exchange timed out: until then its reply may still come (and is dropped)

    @classmethod
    def serial(
        cls, port: str, *, baudrate: int = BAUDRATE, device: str | None = None, **kw: Any
    ) -> RobotiqClient:
        name = device or port
        kw.setdefault("inter_frame_s", modbus.silent_interval(baudrate))
        return cls(SerialLink(port, baudrate, device=name, timeout=kw.get("timeout", 0.5)), device=name, **kw)

    @classmethod
    def tcp(
        cls, host: str, port: int = FORWARDER_PORT, *, device: str | None = None, **kw: Any
    ) -> RobotiqClient:
        name = device or f"{host}:{port}"
        return cls(TcpLink(host, port, device=name, timeout=kw.get("timeout", 0.5)), device=name, **kw)

    @property
    def alive(self) -> bool:
        """Neither closed nor lost (the kit's link keeps the flag)."""
        return self.link.alive

    @property
    def lost(self) -> bool:
        return self.link.lost

    @property
    def trace(self) -> TraceFn | None:
        return self.link.trace

    # -- exchanges ----------------------------------------------------------------------------------------

    def exchange(self, request: bytes, function: int, count: int, *, command: str) -> modbus.Response:
        """Send ``request`` and return its answer (``count`` registers read, or written for 16)."""
        with self._lock:
            if not self.link.alive:
                raise ConnectionLost(
                    f"the link is down ({self.link.lost_reason or 'closed'})",
                    device=self.device,
                    command=command,
                )
            self._parser.reset()
            self._parser.expect(function, count)
            if self._late_until and time.monotonic() < self._late_until:
                # a reply that came after its exchange gave up has the layout of the next one's: drop what
                # arrived before this request (issue 43 §5); only a while after a timeout (it costs a read)
                self.link.discard_input()
            others = self._parser.other_slaves
            if self.inter_frame_s:  # a serial line's t3.5: the device ends a frame on this silence
                wait = self.link.last_rx + self.inter_frame_s - time.monotonic()
                if wait > 0:
                    time.sleep(wait)
            self.link.write(request, command=command)
            if wire_debug():
                log_frame(self.device, TO_GRIPPER, request)
            try:
                reply = self.link.read_decoded(
                    self._parser.feed, time.monotonic() + self.timeout, command=command
                )[0]
            except GripperTimeout:
                self._late_until = time.monotonic() + LATE_WINDOW_TIMEOUTS * self.timeout + LATE_WINDOW_S
                other = self._parser.other_slave if self._parser.other_slaves > others else None
                hint = (
                    f"; slave {other} answered instead: is that the gripper's id? (?slave={other} in the URL)"
                    if other is not None
                    else ""
                )
                raise GripperTimeout(
                    f"no answer from slave {self.slave} within {self.timeout:g} s{hint}",
                    device=self.device,
                    command=command,
                ) from None
            if wire_debug():
                log_frame(self.device, FROM_GRIPPER, reply.raw)
            self.exchanges += 1
        if reply.exception is not None:
            try:
                name = ExceptionCode(reply.exception).name.lower()
            except ValueError:
                name = f"exception_0x{reply.exception:02x}"
            raise CommandFailed(
                f"the gripper answered Modbus exception {reply.exception} ({name})",
                status=reply.exception,
                status_name=name,
                device=self.device,
                command=command,
            )
        return reply

    def read_status(self, *, command: str = "status") -> Status:
        req = modbus.read_request(self.slave, STATUS_ADDRESS, BLOCK_REGISTERS, self.read_function)
        reply = self.exchange(req, self.read_function, BLOCK_REGISTERS, command=command)
        return Status.from_registers(reply.values)

    def write_command(self, cmd: Command, *, command: str = "command") -> None:
        req = modbus.write_request(self.slave, COMMAND_ADDRESS, cmd.registers())
        self.exchange(req, modbus.WRITE_MULTIPLE, BLOCK_REGISTERS, command=command)

    def write_and_read(self, cmd: Command, *, command: str = "command") -> Status:
        """FC 23: the command written and the status read in one exchange (the SDK's cycle)."""
        req = modbus.read_write_request(
            self.slave, STATUS_ADDRESS, BLOCK_REGISTERS, COMMAND_ADDRESS, cmd.registers()
        )
        reply = self.exchange(req, READ_WRITE, BLOCK_REGISTERS, command=command)
        return Status.from_registers(reply.values)

    def close(self) -> None:
        self.link.close()
