"""The Robotiq device client: register exchanges over an RS-485 line (pyserial) or raw RTU over TCP (a UR
robot's tool-communication forwarder), thread-safe, every wait bounded.

Modbus is strictly request/response with one master, so no reader thread is needed: an exchange writes a
request and reads until the parser returns the one answer it expects, under a lock that serialises callers
(a state stream and a motion wait share one line). Errors name the device, the command and the cause:
:class:`GripperTimeout` (no answer), :class:`ConnectionLost` (the link failed), :class:`CommandFailed`
(a Modbus exception), all from drivers/errors.py.
"""

from __future__ import annotations

import contextlib
import socket
import threading
import time
from collections.abc import Callable
from typing import Any, Protocol

from ..dissect import FROM_GRIPPER, TO_GRIPPER
from ..errors import CommandFailed, ConnectionLost, GripperTimeout
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

TraceFn = Callable[[str, bytes], None]  # ("tx" | "rx", bytes): for -vv and the monitor


class ByteLink(Protocol):
    """What the client needs of a transport: write, read what arrived (bounded wait), close."""

    def write(self, data: bytes) -> None: ...

    def read(self, timeout: float) -> bytes: ...

    def close(self) -> None: ...


class SerialLink:
    """An RS-485 adapter (or any pyserial URL: ``socket://``, ``loop://``) at 115200 8N1 by default."""

    def __init__(self, port: str, baudrate: int = BAUDRATE, *, device: str) -> None:
        import serial

        self.device = device
        self.baudrate = baudrate
        try:
            self._port = serial.serial_for_url(
                port, baudrate=baudrate, bytesize=8, parity="N", stopbits=1, timeout=0.0
            )
        except (OSError, ValueError, serial.SerialException) as exc:
            raise ConnectionLost(f"cannot open {port}: {exc}", device=device, command="open") from exc
        self._timeout_set = 0.0

    def write(self, data: bytes) -> None:
        try:
            self._port.write(data)
        except Exception as exc:  # noqa: BLE001 - pyserial raises SerialException, OSError, TypeError
            raise ConnectionLost(f"serial write failed: {exc}", device=self.device) from exc

    def read(self, timeout: float) -> bytes:
        try:
            if timeout != self._timeout_set:
                self._port.timeout = timeout
                self._timeout_set = timeout
            first = self._port.read(1)  # blocks up to timeout for the first byte
            if not first:
                return b""
            waiting = self._port.in_waiting
            return first + (self._port.read(waiting) if waiting else b"")
        except Exception as exc:  # noqa: BLE001
            raise ConnectionLost(f"serial read failed: {exc}", device=self.device) from exc

    def close(self) -> None:
        with contextlib.suppress(Exception):
            self._port.close()


class TcpLink:
    """Raw RTU frames over TCP (a forwarder of the tool connector's RS-485; not Modbus TCP's MBAP framing)."""

    def __init__(self, host: str, port: int = FORWARDER_PORT, *, device: str, timeout: float) -> None:
        self.device = device
        try:
            self._sock = socket.create_connection((host, port), timeout=timeout)
        except OSError as exc:
            raise ConnectionLost(
                f"cannot connect to {host}:{port}: {exc}", device=device, command="open"
            ) from exc
        self._sock.setsockopt(socket.IPPROTO_TCP, socket.TCP_NODELAY, 1)

    def write(self, data: bytes) -> None:
        try:
            self._sock.sendall(data)
        except OSError as exc:
            raise ConnectionLost(f"TCP send failed: {exc}", device=self.device) from exc

    def read(self, timeout: float) -> bytes:
        try:
            self._sock.settimeout(max(timeout, 1e-4))
            data = self._sock.recv(4096)
        except TimeoutError:
            return b""
        except OSError as exc:
            raise ConnectionLost(f"TCP receive failed: {exc}", device=self.device) from exc
        if not data:
            raise ConnectionLost("the forwarder closed the connection", device=self.device)
        return data

    def close(self) -> None:
        with contextlib.suppress(OSError):
            self._sock.close()


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
        self.trace = trace
        self._parser = ResponseParser(slave)
        self._lock = threading.Lock()
        self._last_rx = 0.0
        self._lost: BaseException | None = None
        self.exchanges = 0

    @classmethod
    def serial(
        cls, port: str, *, baudrate: int = BAUDRATE, device: str | None = None, **kw: Any
    ) -> RobotiqClient:
        name = device or port
        kw.setdefault("inter_frame_s", modbus.silent_interval(baudrate))
        return cls(SerialLink(port, baudrate, device=name), device=name, **kw)

    @classmethod
    def tcp(
        cls, host: str, port: int = FORWARDER_PORT, *, device: str | None = None, **kw: Any
    ) -> RobotiqClient:
        name = device or f"{host}:{port}"
        return cls(TcpLink(host, port, device=name, timeout=kw.get("timeout", 0.5)), device=name, **kw)

    @property
    def alive(self) -> bool:
        return self._lost is None

    # -- exchanges ----------------------------------------------------------------------------------------

    def exchange(self, request: bytes, function: int, count: int, *, command: str) -> modbus.Response:
        """Send ``request`` and return its answer (``count`` registers read, or written for 16)."""
        with self._lock:
            if self._lost is not None:
                raise ConnectionLost(f"the link is down ({self._lost})", device=self.device, command=command)
            self._parser.reset()
            self._parser.expect(function, count)
            if self.inter_frame_s:
                wait = self._last_rx + self.inter_frame_s - time.monotonic()
                if wait > 0:
                    time.sleep(wait)
            try:
                self.link.write(request)
                if self.trace:
                    self.trace("tx", request)
                if wire_debug():
                    log_frame(self.device, TO_GRIPPER, request)
                reply = self._read_reply(command)
            except ConnectionLost as exc:
                self._lost = exc
                raise ConnectionLost(exc.message, device=self.device, command=command) from exc
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

    def _read_reply(self, command: str) -> modbus.Response:
        deadline = time.monotonic() + self.timeout
        while True:
            left = deadline - time.monotonic()
            if left <= 0:
                raise GripperTimeout(
                    f"no answer from slave {self.slave} within {self.timeout:g} s",
                    device=self.device,
                    command=command,
                )
            data = self.link.read(left)
            if not data:
                continue
            self._last_rx = time.monotonic()
            if self.trace:
                self.trace("rx", data)
            replies = self._parser.feed(data)
            if replies:
                if wire_debug():
                    log_frame(self.device, FROM_GRIPPER, replies[0].raw)
                return replies[0]

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
        with self._lock:
            if self._lost is None:
                self._lost = ConnectionLost("closed", device=self.device)
        self.link.close()
