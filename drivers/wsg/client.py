"""The WSG client: typed command methods over the :class:`~.connection.WsgConnection` it holds.

Each method is a thin layer over the command table (:mod:`.commands`): it checks its arguments with the
library's one number check (:func:`grippers.drivers.numbers.finite`), names the device and the command in
every error, and runs one exchange. The client HAS a connection (the exchanger: transport, reader thread,
exchanges with their Ctrl-C recovery; :mod:`.connection`, :mod:`.exchanges`), it is not one: no base class,
so what the client is can be read in this file. The matching rules live in :mod:`.session`; the transports
a client opens in :mod:`.opening`.
"""

from __future__ import annotations

from typing import Any, Self

from can import BusABC

from ..errors import GripperError, LimitError
from ..numbers import finite
from .commands import (
    Cmd,
    FingerFlags,
    FingerInfo,
    GraspingState,
    GraspingStatistics,
    SoftLimits,
    SystemFlags,
    SystemInfo,
    SystemLimits,
    command_name,
)
from .connection import WsgConnection
from .exchanges import SILENT_GAP
from .handles import Pending, Queries, Subscription
from .opening import transport_from_url
from .protocol import Status
from .reading import LineOptions, Submitted
from .state_reads import StateReads
from .transports import (
    DEFAULT_BAUDRATE,
    DEFAULT_CAN_RECV_ID,
    DEFAULT_CAN_SEND_ID,
    DEFAULT_TCP_PORT,
    DEFAULT_UDP_LOCAL_PORT,
    DEFAULT_UDP_PORT,
    CanTransport,
    SerialTransport,
    TcpTransport,
    Transport,
    UdpTransport,
)

__all__ = ["Pending", "Queries", "Submitted", "Subscription", "WsgClient"]

_MAX_TAG = 64  # WSG manual 4.0.x §3.5.2
_MAX_LOOP = 256  # WSG manual 4.0.x §3.1.1


class WsgClient:
    """A WSG gripper over one transport. Units are the device's: mm, mm/s, mm/s², N, °C.

    Every method takes ``timeout`` (seconds; default ``timeout`` for state and settings, ``motion_timeout``
    for motions). A device status other than E_SUCCESS raises CommandFailed; a lost line raises
    ConnectionLost for every waiter at once.
    """

    limits: SystemLimits | None = None  # the device's 53h answer, once read

    def __init__(
        self,
        transport: Transport,
        *,
        device: str | None = None,
        timeout: float = 1.0,
        motion_timeout: float = 60.0,
        verify_checksum: bool = True,
        stale_ttl: float = 2.0,
        stale_final_ttl: float = 60.0,
        silent_gap: float = SILENT_GAP,
    ) -> None:
        options = LineOptions(
            device, timeout, motion_timeout, verify_checksum, stale_ttl, stale_final_ttl, silent_gap
        )
        self.connection = WsgConnection(transport, options)
        conn = self.connection
        self._line = conn.line
        self._exchanges = ex = conn.exchanges
        self._motions = conn.motions
        self._call = ex.call
        self._check = ex.check
        # What other modules call on a client, the connection's own (one place each).
        self.request = ex.request
        self.abandon = ex.abandon
        self.resume = ex.resume
        self.submit = conn.callbacks.submit
        self.withdraw = conn.callbacks.withdraw
        self.callbacks_waiting = conn.callbacks.waiting
        self.motion_outstanding = conn.motions.motion_outstanding
        self._reads = StateReads(self._line, ex, conn.callbacks)
        self._query = self._reads.query
        self.queries = self._reads.queries
        self.start_queries = self._reads.start_queries
        self.outstanding = conn.outstanding
        self.subscribe = conn.subscribe
        self.close = conn.close

    # ------------------------------------------------------------------------------------------ factories

    @classmethod
    def tcp(
        cls, host: str, port: int = DEFAULT_TCP_PORT, *, connect_timeout: float | None = None, **kw: Any
    ) -> Self:
        wait = connect_timeout if connect_timeout is not None else kw.get("timeout", 5.0)
        return cls(TcpTransport(host, port, connect_timeout=wait), **kw)

    @classmethod
    def udp(
        cls, host: str, port: int = DEFAULT_UDP_PORT, *, local_port: int = DEFAULT_UDP_LOCAL_PORT, **kw: Any
    ) -> Self:
        return cls(UdpTransport(host, port, local_port=local_port), **kw)

    @classmethod
    def serial(
        cls,
        port: str,
        *,
        baudrate: int = DEFAULT_BAUDRATE,
        bytesize: int = 8,
        parity: str = "N",
        stopbits: float = 1,
        **kw: Any,
    ) -> Self:
        t = SerialTransport(port, baudrate=baudrate, bytesize=bytesize, parity=parity, stopbits=stopbits)
        return cls(t, **kw)

    @classmethod
    def can(
        cls,
        *,
        bus: BusABC | None = None,
        interface: str | None = None,
        channel: str | int | None = None,
        bitrate: int | None = None,
        send_id: int = DEFAULT_CAN_SEND_ID,
        recv_id: int = DEFAULT_CAN_RECV_ID,
        extended_id: bool | None = None,
        port: int | None = None,
        **kw: Any,
    ) -> Self:
        link = CanTransport(
            bus,
            interface=interface,
            channel=channel,
            bitrate=bitrate,
            send_id=send_id,
            recv_id=recv_id,
            extended_id=extended_id,
            port=port,
        )
        return cls(link, **kw)

    @classmethod
    def from_url(cls, url: str, **kw: Any) -> Self:
        """A client on ``url`` (:func:`.opening.transport_from_url`: tcp, udp, serial or can)."""
        return cls(transport_from_url(url, connect_timeout=kw.get("timeout", 5.0)), **kw)

    # ------------------------------------------------------------------------------ the connection's state

    @property
    def device(self) -> str:
        return self._line.device

    @property
    def timeout(self) -> float:
        return self._line.timeout

    @timeout.setter
    def timeout(self, value: float) -> None:
        self._line.timeout = value

    @property
    def motion_timeout(self) -> float:
        return self._line.motion_timeout

    @motion_timeout.setter
    def motion_timeout(self, value: float) -> None:
        self._line.motion_timeout = value

    @property
    def firmware(self) -> Any:
        """The FirmwareVersion of 50h, once read: decides which commands are refused locally."""
        return self._line.firmware

    @firmware.setter
    def firmware(self, value: Any) -> None:
        self._line.firmware = value

    @property
    def stats(self) -> dict[str, int]:
        return self._line.stats

    @property
    def transport(self) -> Transport:
        """The byte line under the connection (as opened, without the wire log)."""
        return self._line.transport

    @property
    def closed(self) -> bool:
        return self.connection.closed

    @property
    def connection_lost(self) -> Any:
        return self.connection.connection_lost

    def __enter__(self) -> Self:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()

    def __repr__(self) -> str:
        return f"<{type(self).__name__} {self.device}{' closed' if self.closed else ''}>"

    def _finish(self, exchange: Any, deadline: float, waited: float, abandon: bool = True) -> None:
        self._motions.finish(exchange, deadline, waited, abandon)

    # ------------------------------------------------------------------------------------------- commands

    def _number(
        self, value: Any, what: str, cmd: int, *, positive: bool = False, low: float | None = None
    ) -> float:
        """``value`` checked by the one number rule, naming the device and ``cmd``; ``positive`` refuses 0."""
        number = finite(value, what, low=low, device=self.device, command=command_name(cmd))
        if positive and number <= 0:
            raise LimitError(
                f"{what} must be positive, not {number:g}", device=self.device, command=command_name(cmd)
            )
        return number

    def _motion(self, cmd: int, wait: bool, timeout: float | None, **fields: Any) -> Pending | None:
        self._exchanges.check_supported(cmd)
        payload = self._exchanges.encode(cmd, **fields)
        try:
            exchange, first, deadline, total = self._motions.start(cmd, payload, timeout)
            if first.status != Status.E_CMD_PENDING or not wait:
                self._motions.done()
                if first.status != Status.E_CMD_PENDING:  # answered at once (an immediate error, or done)
                    self._check(cmd, first)
                    return None if wait else Pending(self, exchange)
                return Pending(self, exchange)
            self._motions.finish(exchange, deadline, total)
        except GripperError:
            raise
        except BaseException:  # Ctrl-C between the steps: abandoned as a timeout is (see exchanges.py)
            self._exchanges.rescue()
            raise
        return None

    def _to_width(
        self, cmd: int, width: float, speed: float, fields: dict[str, Any], relative: bool = False
    ) -> None:
        """A finger motion's width and speed: finite, a width not negative (unless relative), a speed > 0."""
        fields["width"] = self._number(width, "width", cmd, low=None if relative else 0.0)
        fields["speed"] = self._number(speed, "speed", cmd, positive=True)

    # ------------------------------------------------------------------------------------------- motion

    def home(
        self, direction: int | None = None, *, wait: bool = True, timeout: float | None = None
    ) -> Pending | None:
        """Reference the fingers (20h). direction: None/0 configured default, 1 positive, 2 negative."""
        d = 0 if direction is None else int(direction)
        if d not in (0, 1, 2):
            raise LimitError(
                f"homing direction must be 0, 1 or 2, not {direction!r}",
                device=self.device,
                command=command_name(Cmd.HOMING),
            )
        return self._motion(Cmd.HOMING, wait, timeout, direction=d)

    def preposition(
        self,
        width: float,
        speed: float,
        *,
        relative: bool = False,
        stop_on_block: bool = True,
        wait: bool = True,
        timeout: float | None = None,
    ) -> Pending | None:
        """Move the fingers (21h); width absolute, or an offset when ``relative``."""
        fields: dict[str, Any] = {"relative": relative, "stop_on_block": stop_on_block}
        self._to_width(Cmd.PREPOSITION, width, speed, fields, relative)
        return self._motion(Cmd.PREPOSITION, wait, timeout, **fields)

    def grip(
        self,
        width: float,
        speed: float,
        *,
        force: float | None = None,
        wait: bool = True,
        timeout: float | None = None,
    ) -> Pending | None:
        """Grip a part of nominal ``width`` (25h); ``force`` sets the force limit (32h) first."""
        fields: dict[str, Any] = {}
        self._to_width(Cmd.GRIP, width, speed, fields)
        if force is not None:
            self.set_force_limit(force)
        return self._motion(Cmd.GRIP, wait, timeout, **fields)

    def release(
        self, width: float, speed: float, *, wait: bool = True, timeout: float | None = None
    ) -> Pending | None:
        """Open to ``width`` to release a part (26h)."""
        fields: dict[str, Any] = {}
        self._to_width(Cmd.RELEASE, width, speed, fields)
        return self._motion(Cmd.RELEASE, wait, timeout, **fields)

    def stop(self, *, timeout: float | None = None) -> None:
        self._call(Cmd.STOP, timeout=timeout)

    def fast_stop(self, *, timeout: float | None = None) -> None:
        self._call(Cmd.FAST_STOP, timeout=timeout)

    def acknowledge_fast_stop(self, key: bytes = b"ack", *, timeout: float | None = None) -> None:
        """Leave FAST STOP (24h); the key is "ack" (docs/protocols.md §1)."""
        self._call(Cmd.ACK_FAST_STOP, timeout=timeout, key=key)

    # ----------------------------------------------------------------------------------------- settings

    def set_acceleration(self, acceleration: float, *, timeout: float | None = None) -> None:
        value = self._number(acceleration, "acceleration", Cmd.SET_ACCELERATION, positive=True)
        self._call(Cmd.SET_ACCELERATION, timeout=timeout, acceleration=value)

    def acceleration(self, *, timeout: float | None = None) -> float:
        return self._call(Cmd.GET_ACCELERATION, timeout=timeout).fields["acceleration"]

    def set_force_limit(self, force: float, *, timeout: float | None = None) -> None:
        value = self._number(force, "force limit", Cmd.SET_FORCE_LIMIT, positive=True)
        self._call(Cmd.SET_FORCE_LIMIT, timeout=timeout, force=value)

    def force_limit(self, *, timeout: float | None = None) -> float:
        return self._call(Cmd.GET_FORCE_LIMIT, timeout=timeout).fields["force"]

    def set_soft_limits(self, minus: float, plus: float, *, timeout: float | None = None) -> None:
        name = command_name(Cmd.SET_SOFT_LIMITS)
        lo = self._number(minus, "minus", Cmd.SET_SOFT_LIMITS)
        hi = self._number(plus, "plus", Cmd.SET_SOFT_LIMITS)
        if lo > hi:
            raise LimitError(
                f"soft limit minus {lo:g} mm is above plus {hi:g} mm", device=self.device, command=name
            )
        self._call(Cmd.SET_SOFT_LIMITS, timeout=timeout, minus=lo, plus=hi)

    def soft_limits(self, *, timeout: float | None = None) -> SoftLimits:
        """The soft limits; CommandFailed E_NOT_AVAILABLE when none are set (WSG manual 4.0.x §3.3.6)."""
        return self._call(Cmd.GET_SOFT_LIMITS, timeout=timeout).value

    def clear_soft_limits(self, *, timeout: float | None = None) -> None:
        self._call(Cmd.CLEAR_SOFT_LIMITS, timeout=timeout)

    def set_overdrive(self, on: bool, *, timeout: float | None = None) -> None:
        self._call(Cmd.OVERDRIVE, timeout=timeout, enable=bool(on))

    def tare(self, *, timeout: float | None = None) -> None:
        """Zero the force sensor (38h); E_NOT_AVAILABLE without force-sensing fingers (docs/protocols.md
        §1)."""
        self._call(Cmd.TARE, timeout=timeout)

    # -------------------------------------------------------------------------------------------- state

    def system_state(self, *, timeout: float | None = None) -> SystemFlags:
        return self._query(Cmd.GET_SYSTEM_STATE, timeout)

    def grasping_state(self, *, timeout: float | None = None) -> GraspingState | int:
        return self._query(Cmd.GET_GRASPING_STATE, timeout)

    def grasping_statistics(self, reset: bool = False, *, timeout: float | None = None) -> GraspingStatistics:
        return self._call(Cmd.GET_GRASPING_STATISTICS, timeout=timeout, reset=reset).value

    def width(self, *, timeout: float | None = None) -> float:
        return self._query(Cmd.GET_WIDTH, timeout)

    def speed(self, *, timeout: float | None = None) -> float:
        return self._query(Cmd.GET_SPEED, timeout)

    def force(self, *, timeout: float | None = None) -> float:
        return self._query(Cmd.GET_FORCE, timeout)

    def temperature(self, *, timeout: float | None = None) -> float:
        """Device temperature in °C (46h; firmware 4.x)."""
        return self._call(Cmd.GET_TEMPERATURE, timeout=timeout).fields["temperature"]

    def system_info(self, *, timeout: float | None = None) -> SystemInfo:
        """50h; also records ``firmware``, which decides what the client refuses locally."""
        info: SystemInfo = self._call(Cmd.GET_SYSTEM_INFO, timeout=timeout).value
        self.firmware = info.firmware
        return info

    def system_limits(self, *, timeout: float | None = None) -> SystemLimits:
        limits: SystemLimits = self._call(Cmd.GET_SYSTEM_LIMITS, timeout=timeout).value
        self.limits = limits
        return limits

    def device_tag(self, *, timeout: float | None = None) -> str:
        return self._call(Cmd.GET_DEVICE_TAG, timeout=timeout).fields["tag"]

    def set_device_tag(self, tag: str, *, timeout: float | None = None) -> None:
        name = command_name(Cmd.SET_DEVICE_TAG)
        # WSG manual 4.0.x §3.5.2: at most 64 ASCII characters, no control characters.
        if len(tag) > _MAX_TAG:
            raise LimitError(
                f"device tag of {len(tag)} characters exceeds {_MAX_TAG}", device=self.device, command=name
            )
        if any(not (32 <= ord(c) < 127) for c in tag):
            raise LimitError("device tag must be printable ASCII", device=self.device, command=name)
        self._call(Cmd.SET_DEVICE_TAG, timeout=timeout, tag=tag)

    def loop(self, data: bytes, *, timeout: float | None = None) -> bytes:
        """Echo test (06h): returns what the device looped back."""
        if len(data) > _MAX_LOOP:
            raise LimitError(
                f"loop data of {len(data)} bytes exceeds {_MAX_LOOP}",
                device=self.device,
                command=command_name(Cmd.LOOP),
            )
        return self._call(Cmd.LOOP, timeout=timeout, data=bytes(data)).fields["data"]

    # ----------------------------------------------------------------------------------------- fingers

    def _finger(self, n: int, base: int) -> int:
        if n not in (1, 2):
            raise LimitError(
                f"finger must be 1 or 2, not {n!r}", device=self.device, command=command_name(base)
            )
        return base + (0 if n == 1 else 0x10)

    def finger_info(self, n: int, *, timeout: float | None = None) -> FingerInfo:
        return self._call(self._finger(n, Cmd.GET_FINGER1_INFO), timeout=timeout).value

    def finger_flags(self, n: int, *, timeout: float | None = None) -> FingerFlags:
        return self._call(self._finger(n, Cmd.GET_FINGER1_FLAGS), timeout=timeout).fields["flags"]

    def finger_power(self, n: int, on: bool, *, timeout: float | None = None) -> None:
        """Switch a finger's power (62h/72h); switching on pends about 500 ms (WSG manual 4.0.x §3.6.3)."""
        cmd = self._finger(n, Cmd.FINGER1_POWER)
        self._call(cmd, timeout=max(self.timeout, 2.0) if timeout is None else timeout, power=bool(on))

    def finger_data(self, n: int, *, timeout: float | None = None) -> bytes:
        return self._call(self._finger(n, Cmd.GET_FINGER1_DATA), timeout=timeout).fields["data"]
