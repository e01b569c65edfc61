"""Byte transports for the WSG client: TCP, UDP, serial (pyserial) and CAN (python-can).

A transport only moves bytes; framing lives in :mod:`grippers.drivers.wsg.protocol`. ``recv`` returns ``b""``
when nothing arrived within its timeout and raises :class:`ConnectionLost` when the line is gone, so the
reader thread can tell silence from failure. Every transport may be written from one thread while another
reads.
"""

from __future__ import annotations

import math
import select
import socket
import struct
import threading
from collections.abc import Callable
from typing import Any, Protocol

import can
import serial

from ..canlink import describe_failure, open_bus
from ..errors import ConnectionLost, GripperTimeout
from ..serial_ports import open_serial_port
from .protocol import can_frames

__all__ = [
    "DEFAULT_CAN_RECV_ID",
    "DEFAULT_CAN_SEND_ID",
    "DEFAULT_TCP_PORT",
    "DEFAULT_UDP_LOCAL_PORT",
    "DEFAULT_UDP_PORT",
    "CanTransport",
    "SerialTransport",
    "TcpTransport",
    "Transport",
    "UdpTransport",
]

# docs/protocols.md §1, "Transport defaults" (from public drivers, not from the manuals).
DEFAULT_TCP_PORT = 1000
DEFAULT_UDP_PORT = 1500
DEFAULT_UDP_LOCAL_PORT = 1501
DEFAULT_BAUDRATE = 115200
DEFAULT_CAN_SEND_ID = 0x000
DEFAULT_CAN_RECV_ID = 0x001

# A blocked send (full send buffer: the peer stopped reading) fails after this long instead of hanging.
_SEND_TIMEOUT = 2.0
_TIMEVAL = struct.Struct("@ll")  # struct timeval {time_t tv_sec; suseconds_t tv_usec;} (Linux, BSD)


def _timeval(seconds: float) -> bytes:
    # A zero timeval means "wait forever" to SO_RCVTIMEO/SO_SNDTIMEO: the shortest real wait is 1 us.
    micros = max(1, math.ceil(seconds * 1_000_000))
    return _TIMEVAL.pack(micros // 1_000_000, micros % 1_000_000)


def _blocking_with_timeouts(sock: socket.socket) -> None:
    """Put ``sock`` in blocking mode with kernel-side timeouts (SO_RCVTIMEO, SO_SNDTIMEO).

    Why: with a Python socket timeout every recv and send is a poll() plus the call (two system calls and
    two GIL round trips); a blocking socket bounded by the kernel does one, which is most of a round trip's
    cost on a fast link (docs/performance.md, target 2). An expired wait then shows up as BlockingIOError
    (EAGAIN), and shutdown() from another thread still wakes a blocked recv.
    """
    sock.settimeout(None)
    sock.setsockopt(socket.SOL_SOCKET, socket.SO_SNDTIMEO, _timeval(_SEND_TIMEOUT))


class Transport(Protocol):
    """What :class:`~grippers.drivers.wsg.client.WsgClient` needs from a line."""

    name: str
    #: True where the WSG knows about connections (TCP): the client then announces its disconnect with 07h.
    connection_oriented: bool
    #: True on a serial line only: there a pause ends a half-received packet (docs/protocols.md §1,
    #: docs/protocols.md §1). A TCP stream may pause inside a reply (a delayed ACK) and still be whole.
    silent_gap: bool

    def send(self, data: bytes) -> None: ...

    def recv(self, timeout: float) -> bytes: ...

    def recv_nowait(self) -> bytes:
        """What has already arrived, without waiting (b"" for nothing)."""
        ...

    # Optional, where it is cheaper than recv_nowait: ``ready(0)`` is true when something may have arrived.
    # Optional: ``ordered = True`` where replies arrive in the order the device sent them (a stream or one
    # bus; not UDP): an abandoned reply then needs no reorder margin (exchanges.py, "Abandoned callers").

    def close(self) -> None: ...


_DRAIN_READS = 64  # recv_nowait reads at most this many datagrams or frames: bounded under a flood


class _SocketTransport:
    """What the TCP and UDP transports share: a blocking socket whose receive timeout is set only when it
    changes (one thread at a time reads, so the timeout is the reader's), and failures as ConnectionLost."""

    name: str
    _sock: socket.socket
    _timeout: float | None = None

    def _receive_within(self, timeout: float) -> None:
        if timeout != self._timeout:
            self._sock.setsockopt(socket.SOL_SOCKET, socket.SO_RCVTIMEO, _timeval(timeout))
            self._timeout = timeout

    def _lost(self, action: str, exc: OSError) -> ConnectionLost:
        return ConnectionLost(f"{action} failed: {exc}", device=self.name)


class TcpTransport(_SocketTransport):
    ordered = True
    connection_oriented = True
    silent_gap = False

    def __init__(
        self, host: str, port: int = DEFAULT_TCP_PORT, *, connect_timeout: float | None = 5.0
    ) -> None:
        self.name = f"tcp://{host}:{port}"
        try:
            self._sock = socket.create_connection((host, port), timeout=connect_timeout)
        except TimeoutError:
            raise GripperTimeout(f"no TCP connection within {connect_timeout} s", device=self.name) from None
        except OSError as exc:
            raise ConnectionLost(f"cannot connect: {exc}", device=self.name) from None
        self._sock.setsockopt(socket.IPPROTO_TCP, socket.TCP_NODELAY, 1)
        _blocking_with_timeouts(self._sock)
        self._send_lock = threading.Lock()
        self._poll = self.ready = _poller(self._sock)

    def send(self, data: bytes) -> None:
        try:
            with self._send_lock:
                self._sock.sendall(data)
        except OSError as exc:
            raise self._lost("send", exc) from None

    def recv(self, timeout: float) -> bytes:
        self._receive_within(timeout)
        return self._read(0)

    def recv_nowait(self) -> bytes:
        if not self._poll(0):  # the usual answer, and 4x cheaper than a recv that raises EAGAIN
            return b""
        return self._read(socket.MSG_DONTWAIT)

    def _read(self, flags: int) -> bytes:
        """One ``recv``; b"" when nothing came (EAGAIN: SO_RCVTIMEO expired, or nothing for MSG_DONTWAIT)."""
        try:
            data = self._sock.recv(65536, flags)
        except BlockingIOError:
            return b""
        except OSError as exc:
            raise self._lost("receive", exc) from None
        if not data:
            raise ConnectionLost("connection closed by the gripper", device=self.name)
        return data

    def close(self) -> None:
        try:
            self._sock.shutdown(socket.SHUT_RDWR)
        except OSError:
            pass
        self._sock.close()


class UdpTransport(_SocketTransport):
    """One datagram per packet; replies are accepted from the gripper's address only (any source port).

    The socket binds the local address that reaches the gripper (the kernel's route to it: loopback for a
    gripper on loopback), not every interface: nothing on another network can send it replies.
    """

    connection_oriented = False
    silent_gap = False

    def __init__(
        self,
        host: str,
        port: int = DEFAULT_UDP_PORT,
        *,
        local_port: int = DEFAULT_UDP_LOCAL_PORT,
        local_host: str | None = None,
    ) -> None:
        try:
            # The gripper's address decides the family, so wsg+udp://[::1] works as well as IPv4.
            family, _, _, _, peer = socket.getaddrinfo(host, port, 0, socket.SOCK_DGRAM)[0]
            self._peer: tuple[Any, ...] = peer
            if local_host is None:
                local: tuple = _route_source(family, self._peer)
                local = (local[0], local_port, *local[2:])  # IPv6 keeps its flow info and scope id
            else:
                local = (local_host, local_port)
            self._sock = socket.socket(family, socket.SOCK_DGRAM)
            self._sock.bind(local)
            _blocking_with_timeouts(self._sock)
            self._poll = self.ready = _poller(self._sock)
        except OSError as exc:
            raise ConnectionLost(
                f"cannot open UDP {host}:{port} (local port {local_port}): {exc}",
                device=f"udp://{host}:{port}",
            ) from None
        self.local_port = self._sock.getsockname()[1]
        self.name = f"udp://{host}:{port}"

    @property
    def local_address(self) -> tuple[Any, ...]:
        """The address this end is bound to (the one that reaches the gripper, not every interface)."""
        return tuple(self._sock.getsockname())

    def send(self, data: bytes) -> None:
        try:
            self._sock.sendto(data, self._peer)
        except OSError as exc:
            raise self._lost("send", exc) from None

    def recv(self, timeout: float) -> bytes:
        self._receive_within(timeout)
        try:
            data, source = self._sock.recvfrom(65536)
        except BlockingIOError:  # SO_RCVTIMEO expired
            return b""
        except ConnectionRefusedError:
            return b""  # ICMP port unreachable from an earlier send: not a broken link for a datagram socket
        except OSError as exc:
            raise self._lost("receive", exc) from None
        return data if source[0] == self._peer[0] else b""

    def recv_nowait(self) -> bytes:
        if not self._poll(0):
            return b""
        chunks = []
        for _ in range(_DRAIN_READS):
            try:
                data, source = self._sock.recvfrom(65536, socket.MSG_DONTWAIT)
            except (BlockingIOError, ConnectionRefusedError):
                break
            except OSError as exc:
                raise self._lost("receive", exc) from None
            if source[0] == self._peer[0]:
                chunks.append(data)
        return b"".join(chunks)

    def close(self) -> None:
        self._sock.close()


def _poller(sock: socket.socket) -> Callable[[int], list]:
    """``poll(0)`` on ``sock``: whether anything (data, EOF, an error) is waiting, without raising."""
    poller = select.poll()
    poller.register(sock, select.POLLIN)
    return poller.poll


def _route_source(family: int, peer: tuple) -> tuple:
    """The local socket address the kernel would send from to reach ``peer`` (IPv6: with its scope id).

    A connect() on a datagram socket only looks the route up: no packet leaves the machine.
    """
    probe = socket.socket(family, socket.SOCK_DGRAM)
    try:
        probe.connect(peer)
        return probe.getsockname()
    finally:
        probe.close()


class SerialTransport:
    """RS-232 through pyserial; ``port`` may be any pyserial URL (``/dev/ttyUSB0``, ``socket://``, ``loop://``)."""

    ordered = True
    connection_oriented = False
    silent_gap = True

    def __init__(
        self,
        port: str,
        *,
        baudrate: int = DEFAULT_BAUDRATE,
        bytesize: int = 8,
        parity: str = "N",
        stopbits: float = 1,
        write_timeout: float | None = 2.0,
    ) -> None:
        self.name = f"serial:{port}"
        # docs/protocols.md §1: 115200 baud, 8N1 by default; one public driver uses 2 stop bits. Exclusively,
        # as every family opens a port (drivers/serial_ports.py: a second process is told "busy").
        self._port = open_serial_port(
            port,
            device=self.name,
            baudrate=baudrate,
            bytesize=bytesize,
            parity=parity,
            stopbits=stopbits,
            timeout=0.05,
            write_timeout=write_timeout,
        )
        self._timeout = 0.05
        self.port = port

    @property
    def framing(self) -> dict[str, Any]:
        """The line's framing as opened (baudrate, bytesize, parity, stopbits): a reconnection reopens the
        port with it."""
        settings = self._port.get_settings()
        return {key: settings[key] for key in ("baudrate", "bytesize", "parity", "stopbits")}

    def send(self, data: bytes) -> None:
        try:
            self._port.write(data)
            self._port.flush()
        except (serial.SerialException, OSError) as exc:
            raise ConnectionLost(f"send failed: {exc}", device=self.name) from None

    def recv(self, timeout: float) -> bytes:
        try:
            if timeout != self._timeout:
                self._port.timeout = timeout
                self._timeout = timeout
            return self._port.read(max(1, self._port.in_waiting))
        except (serial.SerialException, OSError, TypeError) as exc:
            # TypeError: pyserial's posix read after the fd was closed underneath it.
            raise ConnectionLost(f"receive failed: {exc}", device=self.name) from None

    def recv_nowait(self) -> bytes:
        try:
            waiting = self._port.in_waiting
            return self._port.read(waiting) if waiting else b""
        except (serial.SerialException, OSError, TypeError) as exc:
            raise ConnectionLost(f"receive failed: {exc}", device=self.name) from None

    def close(self) -> None:
        try:
            self._port.close()
        except (serial.SerialException, OSError):
            pass


class CanTransport:
    """WSG packets over CAN: cut into 8-byte frames on ``send_id``, reassembled from ``recv_id`` frames.

    docs/protocols.md §1 (CAN): the whole packet, preamble to checksum, travels in consecutive frames; the
    end of a packet is found by its size field, which the client's parser does, so ``recv`` just returns
    frame data.
    """

    ordered = True
    connection_oriented = False
    silent_gap = False

    def __init__(
        self,
        bus: can.BusABC | None = None,
        *,
        interface: str | None = None,
        channel: str | int | None = None,
        bitrate: int | None = None,
        send_id: int = DEFAULT_CAN_SEND_ID,
        recv_id: int = DEFAULT_CAN_RECV_ID,
        extended_id: bool | None = None,
        send_timeout: float = 1.0,
        port: int | None = None,
    ) -> None:
        self.send_id = send_id
        self.recv_id = recv_id
        self._extended = extended_id if extended_id is not None else max(send_id, recv_id) > 0x7FF
        self._send_timeout = send_timeout
        self._own_bus = bus is None
        if bus is None:
            kwargs: dict[str, Any] = {}
            if bitrate is not None:
                kwargs["bitrate"] = bitrate
            if port is not None:  # python-can's udp_multicast: a private port is a bus of one's own
                kwargs["port"] = port
            try:
                bus = open_bus(interface=interface, channel=channel, **kwargs)
            except (can.CanError, OSError, ValueError, ImportError) as exc:
                raise ConnectionLost(
                    f"cannot open CAN bus: {exc}", device=f"can://{interface}/{channel}"
                ) from None
        self._bus = bus
        self._channel = channel if channel is not None else bus.channel_info  # named in a link failure
        where = f"{interface or ''}/{channel if channel is not None else ''}"
        self.name = f"can://{where}#{send_id:X}/{recv_id:X}"
        mask = 0x1FFFFFFF if self._extended else 0x7FF
        try:
            bus.set_filters([{"can_id": recv_id, "can_mask": mask, "extended": self._extended}])
        except (can.CanError, NotImplementedError):
            pass  # software filtering in recv covers it

    def send(self, data: bytes) -> None:
        try:
            for chunk in can_frames(data):
                msg = can.Message(arbitration_id=self.send_id, data=chunk, is_extended_id=self._extended)
                self._bus.send(msg, timeout=self._send_timeout)
        except (can.CanError, OSError) as exc:
            raise ConnectionLost(describe_failure(exc, self._channel, "send"), device=self.name) from None

    def recv(self, timeout: float) -> bytes:
        try:
            msg = self._bus.recv(timeout)
        except (can.CanError, OSError) as exc:
            raise ConnectionLost(describe_failure(exc, self._channel, "receive"), device=self.name) from None
        return self._data(msg)

    def recv_nowait(self) -> bytes:
        chunks = []
        for _ in range(_DRAIN_READS):
            try:
                msg = self._bus.recv(0.0)
            except (can.CanError, OSError) as exc:
                raise ConnectionLost(
                    describe_failure(exc, self._channel, "receive"), device=self.name
                ) from None
            if msg is None:
                break
            chunks.append(self._data(msg))
        return b"".join(chunks)

    def _data(self, msg: can.Message | None) -> bytes:
        if (
            msg is None
            or msg.arbitration_id != self.recv_id
            or msg.is_error_frame
            or msg.is_remote_frame
            or bool(msg.is_extended_id) != self._extended
        ):
            return b""
        return bytes(msg.data)

    def close(self) -> None:
        if self._own_bus:
            try:
                self._bus.shutdown()
            except (can.CanError, OSError):
                pass
