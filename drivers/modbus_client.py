"""A Modbus client over any of the kit's byte links: RTU on a serial line or a pty, RTU carried over TCP (a
UR robot's tool-communication forwarder, a serial-to-Ethernet gateway in transparent mode), or Modbus TCP
(MBAP), thread-safe, every wait bounded.

Modbus is strictly request/response with one master, so no reader thread is needed: an exchange writes a
request and reads until the codec returns the one answer it expects, under a lock that serialises callers
(a state stream and a motion wait share one line). The rules every register-based family needs are here
once:

- **a deadline** on every exchange (``timeout``): :class:`~grippers.GripperTimeout` names the slave, and
  why a reply did not count when one came (another slave id answered, a bad CRC, a wrong length);
- **a late reply is never the next one's**: for a while after a timeout (``LATE_WINDOW_*``) what arrived
  before a request is dropped before it is sent (an RTU reply carries no request id; Modbus TCP's
  transaction id drops a late reply anyway);
- **a serial line's silence** (``inter_frame_s``, t3.5) is kept before each request;
- **exception replies are typed errors**: :func:`~.modbus.modbus_exception` (``IllegalDataAddress``, ...,
  all :class:`~grippers.CommandFailed`) naming the device, the command and the code;
- **a frame that lies** on Modbus TCP (a false header, a length that does not fit, another unit id) is a
  typed :class:`~.modbus.ModbusFrameError`; the connection's input is dropped so the next exchange starts
  clean.
"""

from __future__ import annotations

import threading
import time
from collections.abc import Callable, Sequence
from typing import Any, Self, TypeVar

from . import modbus
from .dissect import FROM_GRIPPER, TO_GRIPPER
from .errors import ConnectionLost, GripperTimeout, LimitError
from .links import ByteLink, SerialLink, TcpLink, TraceFn
from .modbus import READ_HOLDING, READ_INPUT, ModbusFrameError, Response
from .modbus_tcp import ANY_UNIT, MbapResponseParser, mbap_frame

__all__ = ["FrameLog", "ModbusClient"]

C = TypeVar("C", bound="ModbusClient")

FrameLog = Callable[[str, bytes], None]  # (TO_GRIPPER | FROM_GRIPPER, one whole frame): a wire log

# How long after a timeout the input is dropped before each request: a late reply seen in the field comes
# within a few timeouts (Robotiq, issue 43: 0.6 s against 0.3 s); past this window no read is spent on it.
LATE_WINDOW_TIMEOUTS = 10
LATE_WINDOW_S = 2.0


class ModbusClient:
    """Register exchanges with one device (``slave``: its slave or unit id, 1..247; on Modbus TCP 0xFF too,
    the id of a device that is no gateway) over ``link``.

    ``framing``: ``"rtu"`` (a serial line, or RTU bytes over TCP) or ``"tcp"`` (Modbus TCP, MBAP).
    ``inter_frame_s``: the silence kept before a request after the last byte received (t3.5 on a serial
    line: :meth:`serial` sets it; 0 over TCP). ``frame_log(direction, frame)`` sees each whole frame sent
    and each reply taken (a wire log at debug level); ``trace`` is the link's raw-bytes callback.
    """

    def __init__(
        self,
        link: ByteLink,
        *,
        slave: int = 1,
        device: str | None = None,
        timeout: float = 0.5,
        framing: str = "rtu",
        inter_frame_s: float = 0.0,
        frame_log: FrameLog | None = None,
        trace: TraceFn | None = None,
    ) -> None:
        if framing not in ("rtu", "tcp"):
            raise ValueError(f"framing must be 'rtu' or 'tcp', not {framing!r}")
        if not timeout > 0:
            raise ValueError(f"timeout must be positive, not {timeout!r}")
        if not (framing == "tcp" and slave == ANY_UNIT):  # 0xFF: a Modbus TCP device that is no gateway
            modbus.check_slave(slave)
        self.link = link
        self.device = device or link.device
        self.slave = slave
        self.timeout = timeout
        self.framing = framing
        self.inter_frame_s = inter_frame_s
        self.frame_log = frame_log
        if trace is not None:
            link.trace = trace
        self._rtu = modbus.ResponseParser(slave)
        self._tcp = MbapResponseParser(slave)
        self._transaction = 0
        self._lock = threading.Lock()
        self.exchanges = 0
        self._late_until = 0.0  # an exchange timed out: until then its reply may still come (and is dropped)

    @classmethod
    def serial(
        cls,
        port: str,
        *,
        baudrate: int = 115200,
        device: str | None = None,
        timeout: float = 0.5,
        serial_options: dict[str, Any] | None = None,
        **kw: Any,
    ) -> Self:
        """RTU on a serial port; ``serial_options`` go to pyserial (``{"parity": "E"}``)."""
        name = device or port
        kw.setdefault("inter_frame_s", modbus.silent_interval(baudrate))
        link = SerialLink(port, baudrate, device=name, timeout=timeout, **(serial_options or {}))
        return _owning(link, lambda: cls(link, device=name, timeout=timeout, **kw))

    @classmethod
    def tcp(
        cls,
        host: str,
        port: int,
        *,
        framing: str = "tcp",
        device: str | None = None,
        timeout: float = 0.5,
        **kw: Any,
    ) -> Self:
        """Modbus TCP (``framing="tcp"``; port 502 on most devices) or RTU bytes over TCP (``"rtu"``)."""
        name = device or f"{host}:{port}"
        link = TcpLink(host, port, device=name, timeout=timeout)
        return _owning(link, lambda: cls(link, device=name, framing=framing, timeout=timeout, **kw))

    @property
    def alive(self) -> bool:
        """Neither closed nor lost (the link keeps the flag)."""
        return self.link.alive

    @property
    def lost(self) -> bool:
        return self.link.lost

    @property
    def trace(self) -> TraceFn | None:
        return self.link.trace

    # -- the one exchange -----------------------------------------------------------------------------------

    def exchange(self, pdu: bytes, count: int, *, command: str) -> Response:
        """Send request ``pdu`` and return its answer (``count`` registers read, or written for 16).

        Raises :class:`~grippers.GripperTimeout`, :class:`~grippers.ConnectionLost`, a typed
        :class:`~.modbus.ModbusException` for an exception reply, or a :class:`~.modbus.ModbusFrameError`."""
        if not pdu:
            raise LimitError("an empty request", device=self.device, command=command)
        function = pdu[0]
        with self._lock:
            if not self.link.alive:
                raise ConnectionLost(
                    f"the link is down ({self.link.lost_reason or 'closed'})",
                    device=self.device,
                    command=command,
                )
            request, feed = self._framed(pdu, function, count)
            if self._late_until and time.monotonic() < self._late_until:
                # a reply that came after its exchange gave up has the layout of the next one's: drop what
                # arrived before this request; only a while after a timeout (it costs a read)
                self.link.discard_input()
            others = self._rtu.other_slaves
            if self.inter_frame_s:  # a serial line's t3.5: the device ends a frame on this silence
                wait = self.link.last_rx + self.inter_frame_s - time.monotonic()
                if wait > 0:
                    time.sleep(wait)
            self.link.write(request, command=command)
            if self.frame_log is not None:
                self.frame_log(TO_GRIPPER, request)
            try:
                reply = self.link.read_decoded(feed, time.monotonic() + self.timeout, command=command)[0]
            except GripperTimeout:
                self._late_until = time.monotonic() + LATE_WINDOW_TIMEOUTS * self.timeout + LATE_WINDOW_S
                raise self._timeout(command, others) from self._rtu.last_error
            except ModbusFrameError as exc:
                self.link.discard_input()  # the stream is out of step: start the next exchange clean
                self._late_until = time.monotonic() + LATE_WINDOW_TIMEOUTS * self.timeout + LATE_WINDOW_S
                raise _named(exc, self.device, command) from None
            if self.frame_log is not None:
                self.frame_log(FROM_GRIPPER, reply.raw)
            self.exchanges += 1
        if reply.exception is not None:
            raise modbus.modbus_exception(reply.exception, function, device=self.device, command=command)
        return reply

    def _framed(
        self, pdu: bytes, function: int, count: int
    ) -> tuple[bytes, Callable[[bytes], Sequence[Response]]]:
        if self.framing == "tcp":
            self._transaction = (self._transaction + 1) & 0xFFFF
            self._tcp.reset()
            self._tcp.expect(self._transaction, function, count)
            return mbap_frame(self._transaction, self.slave, pdu), self._tcp.feed
        self._rtu.reset()
        self._rtu.expect(function, count)
        return modbus.rtu_frame(self.slave, pdu), self._rtu.feed

    def _timeout(self, command: str, others: int) -> GripperTimeout:
        parser = self._rtu
        other = parser.other_slave if self.framing == "rtu" and parser.other_slaves > others else None
        if other is not None:
            hint = f"; slave {other} answered instead: is that the device's id? (?slave={other} in the URL)"
        elif self.framing == "rtu" and parser.last_error is not None:
            hint = f"; dropped: {parser.last_error.message}"
        else:
            hint = ""
        return GripperTimeout(
            f"no answer from slave {self.slave} within {self.timeout:g} s{hint}",
            device=self.device,
            command=command,
        )

    # -- the function codes ---------------------------------------------------------------------------------

    def _pdu(self, build: Callable[..., bytes], *args: Any, command: str) -> bytes:
        """A request built from the caller's numbers; a number no frame holds is a
        :class:`~grippers.LimitError` naming the device and the command, and nothing is sent."""
        try:
            return build(*args)
        except ValueError as exc:
            raise LimitError(str(exc), device=self.device, command=command) from None

    def read_registers(
        self, address: int, count: int, *, function: int = READ_HOLDING, command: str = "read"
    ) -> tuple[int, ...]:
        """FC 03 (holding registers, the default) or 04 (input registers)."""
        pdu = self._pdu(modbus.read_pdu, address, count, function, command=command)
        return self.exchange(pdu, count, command=command).values

    def read_holding_registers(self, address: int, count: int, *, command: str = "read") -> tuple[int, ...]:
        return self.read_registers(address, count, function=READ_HOLDING, command=command)

    def read_input_registers(self, address: int, count: int, *, command: str = "read") -> tuple[int, ...]:
        return self.read_registers(address, count, function=READ_INPUT, command=command)

    def write_registers(self, address: int, values: Sequence[int], *, command: str = "write") -> None:
        """FC 16; the echo must name the registers written (:class:`~.modbus.ModbusFrameError` otherwise)."""
        values = list(values)
        pdu = self._pdu(modbus.write_pdu, address, values, command=command)
        reply = self.exchange(pdu, len(values), command=command)
        if (reply.address, reply.count) != (address, len(values)):
            raise _named(
                modbus.ModbusLengthError(
                    f"the write of {len(values)} registers at {address} was echoed as "
                    f"{reply.count} at {reply.address}"
                ),
                self.device,
                command,
            )

    def read_write_registers(
        self,
        read_address: int,
        read_count: int,
        write_address: int,
        values: Sequence[int],
        *,
        command: str = "read/write",
    ) -> tuple[int, ...]:
        """FC 23: ``values`` written at ``write_address``, then ``read_count`` registers read, in one
        exchange (the device writes first)."""
        pdu = self._pdu(
            modbus.read_write_pdu, read_address, read_count, write_address, list(values), command=command
        )
        return self.exchange(pdu, read_count, command=command).values

    def close(self) -> None:
        self.link.close()

    def __enter__(self) -> ModbusClient:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()


def _owning(link: ByteLink, make: Callable[[], C]) -> C:
    """A client made over a link just opened for it; the link is closed if the client refuses its settings."""
    try:
        return make()
    except BaseException:
        link.close()
        raise


def _named(exc: ModbusFrameError, device: str, command: str) -> ModbusFrameError:
    """The codec's error (raised without knowing the device) again, naming the device and the command."""
    if isinstance(exc, modbus.ModbusUnitError):
        return modbus.ModbusUnitError(exc.message, unit=exc.unit, device=device, command=command)
    return type(exc)(exc.message, device=device, command=command)
