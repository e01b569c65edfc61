"""Fixtures for the WSG simulator tests: a direct model driver and servers on every transport.

Test files import nothing from here (pytest runs with --import-mode=importlib); they ask for fixtures.
"""

from __future__ import annotations

import itertools
import os
import select
import socket
import time
import tty
from collections.abc import Callable, Iterator
from urllib.parse import parse_qs, urlsplit

import can
import pytest

from grippers.drivers.wsg.commands import Reply, decode_reply, encode_request
from grippers.drivers.wsg.protocol import Packet, PacketParser, can_frames, encode_packet
from grippers.drivers.wsg.sim import SimServer, WsgModel, serve

from ...closing import closed_after

TIME_SCALE = 50.0
_channels = itertools.count()


def decode_all(chunks: list[bytes]) -> list[Reply]:
    """Replies in the packets the model produced (each packet decoded with the client's codec)."""
    parser = PacketParser()
    out = []
    for chunk in chunks:
        for item in parser.feed(chunk):
            assert isinstance(item, Packet), item
            out.append(decode_reply(item.command, item.payload))
    return out


class ModelDriver:
    """Talks to a :class:`WsgModel` by direct calls, keeping a simulated time that tests move on."""

    def __init__(self, model: WsgModel) -> None:
        self.model = model
        self.now = 0.0

    def raw(self, command: int, payload: bytes = b"", *, conn: int = 0) -> list[Reply]:
        return decode_all(self.model.handle(Packet(command, payload), self.now, conn))

    def call(self, command: int, *, conn: int = 0, **fields: object) -> list[Reply]:
        return self.raw(command, encode_request(command, **fields), conn=conn)

    def one(self, command: int, *, conn: int = 0, **fields: object) -> Reply:
        replies = self.call(command, conn=conn, **fields)
        assert len(replies) == 1, replies
        return replies[0]

    def advance(self, seconds: float) -> list[Reply]:
        self.now += seconds
        return decode_all(self.model.advance(self.now))

    def until_done(self, command: int, limit: float = 30.0, step: float = 0.01) -> Reply:
        """Advance until the final reply of ``command`` arrives; other packets are dropped."""
        end = self.now + limit
        while self.now < end:
            for reply in self.advance(step):
                if reply.command == command:
                    return reply
        raise AssertionError(f"no final reply to {command:#04x} within {limit} s")

    def home(self, direction: int = 0) -> None:
        assert self.one(0x20, direction=direction).pending
        assert self.until_done(0x20).ok


@pytest.fixture
def make_driver() -> Callable[..., ModelDriver]:
    return lambda **params: ModelDriver(WsgModel(**params))


@pytest.fixture
def driver() -> ModelDriver:
    return ModelDriver(WsgModel())


@pytest.fixture
def homed(driver: ModelDriver) -> ModelDriver:
    driver.home()
    return driver


@pytest.fixture
def decode() -> Callable[[list[bytes]], list[Reply]]:
    return decode_all


@pytest.fixture
def start_server() -> Iterator[Callable[..., SimServer]]:
    """serve() with a large time scale; every server is closed after the test."""

    def start(listen: str, *, time_scale: float = TIME_SCALE, **params: object) -> SimServer:
        return serve(WsgModel(**params), listen, time_scale=time_scale)

    with closed_after(start) as started:
        yield started


@pytest.fixture
def can_channel() -> str:
    """A virtual CAN channel no other test uses."""
    return f"wsg-sim-{os.getpid()}-{next(_channels)}"


@pytest.fixture
def raw_tcp_address(start_server: Callable[..., SimServer]) -> tuple[str, int]:
    """Host and port of a simulated WSG 50 holding a 40 mm part, for the raw-socket client test."""
    server = start_server("tcp://127.0.0.1:0", part_width_mm=40.0)
    host, port = server.url.removeprefix("wsg+tcp://").rsplit(":", 1)
    return host, int(port)


class Wire:
    """A minimal client over a byte transport, using the driver's codec: send requests, wait for replies."""

    def __init__(self, send, recv, close) -> None:
        self._send, self._recv, self._close = send, recv, close
        self.parser = PacketParser()
        self.events: list = []  # checksum errors and discarded bytes seen so far
        self.backlog: list[Packet] = []

    def send_raw(self, data: bytes) -> None:
        self._send(data)

    def send(self, command: int, **fields: object) -> None:
        self._send(encode_packet(command, encode_request(command, **fields)))

    def packets(self, timeout: float = 2.0) -> list[Packet]:
        """Whatever complete packets arrive within ``timeout`` (returns as soon as one batch is in)."""
        if self.backlog:
            out, self.backlog = self.backlog, []
            return out
        deadline = time.monotonic() + timeout
        while True:
            remaining = deadline - time.monotonic()
            if remaining <= 0:
                return []
            data = self._recv(remaining)
            if not data:
                continue
            out = []
            for item in self.parser.feed(data):
                (out if isinstance(item, Packet) else self.events).append(item)
            if out:
                return out

    def expect(self, command: int, timeout: float = 3.0, *, skip_pending: bool = False) -> Reply:
        """The next reply carrying ``command``; other packets are kept for later."""
        deadline = time.monotonic() + timeout
        kept: list[Packet] = []
        try:
            while time.monotonic() < deadline:
                batch = self.packets(deadline - time.monotonic())
                for i, packet in enumerate(batch):
                    if packet.command != command:
                        kept.append(packet)
                        continue
                    reply = decode_reply(packet.command, packet.payload)
                    if skip_pending and reply.pending:
                        continue
                    kept.extend(batch[i + 1 :])
                    return reply
            raise AssertionError(f"no reply to {command:#04x} within {timeout} s")
        finally:
            self.backlog = kept + self.backlog

    def request(self, command: int, timeout: float = 3.0, **fields: object) -> Reply:
        self.send(command, **fields)
        return self.expect(command, timeout)

    def run(self, command: int, timeout: float = 5.0, **fields: object) -> Reply:
        """An async command: expects E_CMD_PENDING, returns the final reply."""
        first = self.request(command, **fields)
        assert first.pending, first
        return self.expect(command, timeout, skip_pending=True)

    def close(self) -> None:
        self._close()


def _tcp_wire(url: str) -> Wire:
    host, port = url.removeprefix("wsg+tcp://").rsplit(":", 1)
    sock = socket.create_connection((host, int(port)), timeout=2.0)

    def recv(timeout: float) -> bytes:
        sock.settimeout(max(timeout, 0.001))
        try:
            data = sock.recv(65536)
        except TimeoutError:
            return b""
        if not data:
            raise ConnectionResetError("simulator closed the connection")
        return data

    wire = Wire(sock.sendall, recv, sock.close)
    wire.sock = sock  # type: ignore[attr-defined]
    return wire


def _udp_wire(url: str) -> Wire:
    parts = urlsplit(url)
    sock = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
    sock.bind(("127.0.0.1", 0))
    address = (parts.hostname, parts.port)

    def recv(timeout: float) -> bytes:
        sock.settimeout(max(timeout, 0.001))
        try:
            return sock.recv(65536)
        except TimeoutError:
            return b""

    return Wire(lambda data: sock.sendto(data, address), recv, sock.close)


def _pty_wire(url: str) -> Wire:
    fd = os.open(url.removeprefix("wsg+serial://"), os.O_RDWR | os.O_NOCTTY)
    tty.setraw(fd)

    def recv(timeout: float) -> bytes:
        ready, _, _ = select.select([fd], [], [], max(timeout, 0.0))
        return os.read(fd, 65536) if ready else b""

    def send(data: bytes) -> None:
        os.write(fd, data)

    return Wire(send, recv, lambda: os.close(fd))


def _can_wire(url: str) -> Wire:
    parts = urlsplit(url)
    query = {k: int(v[-1], 0) for k, v in parse_qs(parts.query).items() if k != "bitrate"}
    send_id, recv_id = query.get("send_id", 0x000), query.get("recv_id", 0x001)
    bus = can.Bus(interface=parts.netloc, channel=parts.path.lstrip("/"))
    frames: list[can.Message] = []

    def send(data: bytes) -> None:
        for chunk in can_frames(data):
            bus.send(can.Message(arbitration_id=send_id, data=chunk, is_extended_id=send_id > 0x7FF))

    def recv(timeout: float) -> bytes:
        msg = bus.recv(timeout=max(timeout, 0.0))
        if msg is None or msg.arbitration_id != recv_id:
            return b""
        frames.append(msg)
        return bytes(msg.data)

    wire = Wire(send, recv, bus.shutdown)
    wire.frames = frames  # type: ignore[attr-defined]
    return wire


@pytest.fixture
def open_wire() -> Iterator[Callable[[str], Wire]]:
    """Open a raw client on a simulator's family URL (wsg+tcp / wsg+udp / wsg+serial / wsg+can)."""
    wires: list[Wire] = []
    openers = {"wsg+tcp": _tcp_wire, "wsg+udp": _udp_wire, "wsg+serial": _pty_wire, "wsg+can": _can_wire}

    def open_(url: str) -> Wire:
        wire = openers[url.split(":", 1)[0]](url)
        wires.append(wire)
        return wire

    yield open_
    for wire in wires:
        try:
            wire.close()
        except OSError:
            pass
