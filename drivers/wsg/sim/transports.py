"""The four ways a simulated WSG is reached: TCP, UDP, a pseudo-terminal and a python-can bus.

Each class only moves bytes; parsing, the model, faults and timing live in :class:`~.engine.SimServer`.
"""

from __future__ import annotations

import contextlib
import functools
import os
import selectors
import socket
import tty
from collections import OrderedDict
from typing import Any

import can

from ...canlink import is_link_failure
from ...inet import family_of, tcp_listener
from ...urls import format_host
from ..protocol import PacketParser, can_frames
from .engine import Link, SimServer
from .model import WsgModel


class _SelectorServer(SimServer):
    """A server whose inputs are file descriptors: a selector plus a socketpair to wake it."""

    def __init__(self, model: WsgModel, *, time_scale: float) -> None:
        super().__init__(model, time_scale=time_scale)
        self._selector = selectors.DefaultSelector()
        self._wake_r, self._wake_w = socket.socketpair()
        self._wake_r.setblocking(False)
        self._wake_w.setblocking(False)
        self._selector.register(self._wake_r, selectors.EVENT_READ, None)

    def _parser(self) -> PacketParser:
        return PacketParser(verify_checksum=self.model.verify_checksum)

    def _wake(self) -> None:
        with contextlib.suppress(OSError):
            self._wake_w.send(b"\0")

    def _wait_and_read(self, timeout: float) -> None:
        for key, _ in self._selector.select(timeout):
            if key.fileobj is self._wake_r:
                with contextlib.suppress(OSError):
                    self._wake_r.recv(4096)
            else:
                key.data()

    def _close_transport(self) -> None:
        self._selector.close()
        self._wake_r.close()
        self._wake_w.close()


class TcpSimServer(_SelectorServer):
    """Several clients at once, each its own model connection (07h, auto updates, FAST STOP on drop)."""

    def __init__(self, model: WsgModel, host: str, port: int, *, time_scale: float) -> None:
        super().__init__(model, time_scale=time_scale)
        self._listener = tcp_listener(host, port)
        self._listener.setblocking(False)
        self._clients: dict[int, tuple[socket.socket, Link]] = {}
        self._selector.register(self._listener, selectors.EVENT_READ, self._accept)
        self.address = self._listener.getsockname()[:2]
        self.url = f"wsg+tcp://{format_host(self.address[0], self.address[1])}"
        self._start(f"wsg-sim-tcp-{self.address[1]}")

    def _accept(self) -> None:
        try:
            sock, peer = self._listener.accept()
        except OSError:
            return
        sock.setblocking(True)
        sock.settimeout(1.0)  # a peer that stops reading must not stall the simulator for good
        sock.setsockopt(socket.IPPROTO_TCP, socket.TCP_NODELAY, 1)
        with self.lock:
            conn = self.model.connect(connection_oriented=True)
            link = Link(conn, self._parser(), sock.sendall, f"tcp {peer[0]}:{peer[1]}")
            self._add_link(link)
            self._clients[conn] = (sock, link)
        self._selector.register(sock, selectors.EVENT_READ, lambda: self._readable(sock, link))

    def _readable(self, sock: socket.socket, link: Link) -> None:
        try:
            data = sock.recv(65536)
        except (BlockingIOError, TimeoutError):
            return
        except OSError:
            data = b""
        if data:
            self._received(link, data)
        else:
            self._lost_link(link)

    def _lost_link(self, link: Link) -> None:
        super()._lost_link(link)
        entry = self._clients.pop(link.conn, None)
        if entry is not None:
            with contextlib.suppress(KeyError, ValueError):
                self._selector.unregister(entry[0])
            entry[0].close()

    def _drop_links(self) -> None:
        # Sim choice: a server-side drop is still an unannounced end of the connection, so the model enters
        # FAST STOP exactly as when the client vanishes (the gripper cannot tell who broke the link).
        for _, link in list(self._clients.values()):
            self._lost_link(link)

    def _close_transport(self) -> None:
        for sock, _ in self._clients.values():
            sock.close()
        self._clients.clear()
        self._listener.close()
        super()._close_transport()


class UdpSimServer(_SelectorServer):
    """Answers every datagram to its sender's address; each sender address is one model connection.

    At most ``max_peers`` addresses are remembered: a new one beyond that makes the simulator forget the
    peer that has been silent longest (its auto updates end), so a stream of datagrams from ever new
    source ports cannot grow its memory without bound.
    """

    def __init__(
        self, model: WsgModel, host: str, port: int, *, time_scale: float, max_peers: int = 64
    ) -> None:
        super().__init__(model, time_scale=time_scale)
        self._sock = socket.socket(family_of(host), socket.SOCK_DGRAM)
        self._sock.bind((host, port))
        self._sock.setblocking(False)
        self.max_peers = max_peers
        self._peers: OrderedDict[tuple, Link] = OrderedDict()  # least recently heard first
        self._selector.register(self._sock, selectors.EVENT_READ, self._readable)
        self.address = self._sock.getsockname()[:2]
        # The simulator replies to the sender's port, so the client may bind any local port.
        self.url = f"wsg+udp://{format_host(self.address[0], self.address[1])}?local_port=0"
        self._start(f"wsg-sim-udp-{self.address[1]}")

    def _readable(self) -> None:
        while True:
            try:
                data, peer = self._sock.recvfrom(65536)
            except (BlockingIOError, InterruptedError):
                return
            except OSError:  # e.g. ICMP port unreachable from an earlier send
                continue
            link = self._peers.get(peer)
            if link is None:
                with self.lock:
                    while len(self._peers) >= self.max_peers:
                        _, old = self._peers.popitem(last=False)
                        self._links.pop(old.conn, None)
                        self.model.disconnect(old.conn)
                    conn = self.model.connect(connection_oriented=False)
                    link = Link(
                        conn, self._parser(), functools.partial(self._sendto, peer=peer), f"udp {peer}"
                    )
                    self._add_link(link)
                    self._peers[peer] = link
            else:
                self._peers.move_to_end(peer)
            self._received(link, data, datagram=True)

    @property
    def peers(self) -> int:
        """How many sender addresses the simulator remembers now."""
        return len(self._peers)

    def _sendto(self, data: bytes, peer: tuple) -> None:
        with contextlib.suppress(BlockingIOError):
            self._sock.sendto(data, peer)

    def _close_transport(self) -> None:
        self._sock.close()
        self._peers.clear()
        super()._close_transport()


class PtySimServer(_SelectorServer):
    """A serial line: the client opens the slave end (``.url`` names it) as it would /dev/ttyUSB0."""

    def __init__(self, model: WsgModel, *, time_scale: float) -> None:
        super().__init__(model, time_scale=time_scale)
        self._master, self._slave = os.openpty()
        # Raw line discipline: no echo, no CR/LF translation of binary packets. The simulator keeps its own
        # slave fd open so a client closing and reopening the port never makes the master read EIO.
        tty.setraw(self._slave)
        os.set_blocking(self._master, False)
        self.path = os.ttyname(self._slave)
        self.url = f"wsg+serial://{self.path}"
        with self.lock:
            conn = self.model.connect(connection_oriented=False)
            self._link = Link(conn, self._parser(), self._write, f"pty {self.path}", silent_gap=True)
            self._add_link(self._link)
        self._selector.register(self._master, selectors.EVENT_READ, self._readable)
        self._start(f"wsg-sim-pty-{os.path.basename(self.path)}")

    def _readable(self) -> None:
        try:
            data = os.read(self._master, 65536)
        except (BlockingIOError, InterruptedError):
            return
        except OSError:  # EIO: no slave open (cannot happen while we hold one, but never die of it)
            return
        if data:
            self._received(self._link, data)

    def _write(self, data: bytes) -> None:
        """Like a UART with nobody listening, bytes the line cannot take are lost instead of blocking."""
        view = memoryview(data)
        while view:
            try:
                n = os.write(self._master, view)
            except BlockingIOError:
                return
            view = view[n:]

    def _close_transport(self) -> None:
        with contextlib.suppress(KeyError, ValueError):
            self._selector.unregister(self._master)
        os.close(self._master)
        os.close(self._slave)
        super()._close_transport()


class CanSimServer(SimServer):
    """WSG packets cut into 8-byte frames (docs/protocols.md §1, CAN) on any python-can bus.

    ``send_id``/``recv_id`` are the CLIENT's ids, as in the family URL: the simulator receives on
    ``send_id`` and answers on ``recv_id``.
    """

    def __init__(
        self,
        model: WsgModel,
        *,
        interface: str,
        channel: str,
        send_id: int = 0x000,
        recv_id: int = 0x001,
        bitrate: int | None = None,
        bus: can.BusABC | None = None,
        extended_id: bool = False,
        time_scale: float,
    ) -> None:
        # The WSG uses standard frames (docs/protocols.md §1, CAN): an 11-bit identifier is 0..0x7FF, a 29-bit
        # one 0..0x1FFFFFFF; an id the frame format cannot carry is refused, never sent in another format.
        top = 0x1FFFFFFF if extended_id else 0x7FF
        for what, value in (("send_id", send_id), ("recv_id", recv_id)):
            if not 0 <= value <= top:
                fmt = "an extended (29-bit)" if extended_id else "a standard (11-bit)"
                raise ValueError(f"{what} {value:#x} is not valid for {fmt} CAN frame (0..{top:#x})")
        self._extended = extended_id
        super().__init__(model, time_scale=time_scale)
        self._own_bus = bus is None
        kwargs: dict[str, Any] = {} if bitrate is None else {"bitrate": bitrate}
        self._bus = bus if bus is not None else can.Bus(interface=interface, channel=channel, **kwargs)
        self._rx_id, self._tx_id = send_id, recv_id
        query = []
        if send_id != 0x000:
            query.append(f"send_id=0x{send_id:X}")
        if recv_id != 0x001:
            query.append(f"recv_id=0x{recv_id:X}")
        if bitrate is not None:
            query.append(f"bitrate={bitrate}")
        if extended_id:
            query.append("extended=1")
        self.url = f"wsg+can://{interface}/{channel}" + ("?" + "&".join(query) if query else "")
        with self.lock:
            conn = self.model.connect(connection_oriented=False)
            self._link = Link(
                conn,
                PacketParser(verify_checksum=model.verify_checksum),
                self._send_frames,
                f"can {interface}/{channel}",
            )
            self._add_link(self._link)
        self._start(f"wsg-sim-can-{channel}")

    def _wait_and_read(self, timeout: float) -> None:
        msg = self._recv(timeout)
        while msg is not None:
            if (
                msg.arbitration_id == self._rx_id
                and not msg.is_remote_frame
                and not msg.is_error_frame
                and bool(msg.is_extended_id) == self._extended
                and msg.dlc
            ):
                self._received(self._link, bytes(msg.data))
            msg = self._recv(0.0)

    def _recv(self, timeout: float) -> can.Message | None:
        """The next frame, or None. The host's interface going down (ip link set vcan0 down) is not the
        simulator's end: a gripper on the wire would not notice, so the simulated one keeps running and hears
        nothing until it is up again. Every read, the first and those that drain the queue after it (the
        interface may go down between them: a busy CI run ended the simulator's thread there)."""
        try:
            return self._bus.recv(timeout=timeout)
        except can.CanError as exc:
            if not is_link_failure(exc):
                raise
            return None

    def _send_frames(self, data: bytes) -> None:
        extended = self._extended
        for chunk in can_frames(data):
            self._bus.send(
                can.Message(arbitration_id=self._tx_id, data=chunk, is_extended_id=extended), timeout=0.5
            )

    def _send(self, link: Link, data: bytes) -> None:
        try:
            link.send(data)
        except can.CanError:
            pass  # a full or absent bus loses the packet; the client's timeout covers it

    def _close_transport(self) -> None:
        if self._own_bus:
            self._bus.shutdown()
