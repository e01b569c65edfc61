"""The backend kit's byte links over a real pty and loopback TCP: bounded reads, typed errors naming the
device and the command, the lost flag when the peer goes away, close, and swap on reconnect."""

from __future__ import annotations

import os
import socket
import threading
import time
import tty
from collections.abc import Iterator

import pytest

from grippers import ConnectionLost, GripperTimeout, ProtocolError, URLError
from grippers.kit import ByteLink, LinkHolder, SerialLink, TcpLink, open_link

SHORT = 0.05  # a read that must time out: nothing is ever sent, so no race with the scheduler


class Pty:
    """Both ends of a raw pseudo-terminal: the link opens ``path``, the test is the device on ``master``."""

    def __init__(self) -> None:
        self.master, self.slave = os.openpty()
        tty.setraw(self.slave)
        self.path = os.ttyname(self.slave)

    def send(self, data: bytes) -> None:
        os.write(self.master, data)

    def hang_up(self) -> None:
        if self.master >= 0:
            os.close(self.master)
            self.master = -1

    def close(self) -> None:
        self.hang_up()
        os.close(self.slave)


class Peer:
    """A loopback TCP listener; ``accept()`` gives the test the device end of the next connection."""

    def __init__(self) -> None:
        self.listener = socket.create_server(("127.0.0.1", 0))
        self.port = self.listener.getsockname()[1]
        self.conns: list[socket.socket] = []

    def accept(self) -> socket.socket:
        self.listener.settimeout(10)
        conn, _ = self.listener.accept()
        self.conns.append(conn)
        return conn

    def close(self) -> None:
        for c in self.conns:
            c.close()
        self.listener.close()


@pytest.fixture
def pty() -> Iterator[Pty]:
    p = Pty()
    yield p
    p.close()


@pytest.fixture
def peer() -> Iterator[Peer]:
    p = Peer()
    yield p
    p.close()


def _link_pair(kind: str, pty: Pty, peer: Peer) -> tuple[ByteLink, object]:
    if kind == "pty":
        return SerialLink(pty.path, device="dev-under-test"), pty
    link = TcpLink("127.0.0.1", peer.port, device="dev-under-test")
    return link, peer.accept()


def _send(far: object, data: bytes) -> None:
    if isinstance(far, Pty):
        far.send(data)
    else:
        assert isinstance(far, socket.socket)
        far.sendall(data)


def _hang_up(far: object) -> None:
    if isinstance(far, Pty):
        far.hang_up()
    else:
        assert isinstance(far, socket.socket)
        far.close()


@pytest.mark.parametrize("kind", ["pty", "tcp"])
def test_reads_are_bounded_and_framed(kind: str, pty: Pty, peer: Peer) -> None:
    link, far = _link_pair(kind, pty, peer)
    with link:
        started = time.monotonic()
        with pytest.raises(GripperTimeout) as caught:
            link.read_exactly(4, time.monotonic() + SHORT, command="status")
        assert time.monotonic() - started < 5.0
        assert (caught.value.device, caught.value.command) == ("dev-under-test", "status")
        assert isinstance(caught.value, TimeoutError) and not link.lost and link.alive
        assert link.read(SHORT) == b""  # silence is not an error

        _send(far, b"ab")
        with pytest.raises(GripperTimeout, match="got 2"):  # half a frame, then nothing: still bounded
            link.read_exactly(4, time.monotonic() + 0.3, command="status")
        _send(far, b"cdef\nrest")
        assert link.read_exactly(4, command="status") == b"abcd"  # the bytes kept from the timed-out read
        assert link.read_until(b"\n", command="line") == b"ef\n"
        assert link.read_exactly(4) == b"rest"


@pytest.mark.parametrize("kind", ["pty", "tcp"])
def test_the_lost_flag_is_set_when_the_peer_goes_away(kind: str, pty: Pty, peer: Peer) -> None:
    link, far = _link_pair(kind, pty, peer)
    with link:
        assert not link.lost
        _hang_up(far)
        with pytest.raises(ConnectionLost) as caught:
            link.read_exactly(1, time.monotonic() + 10, command="status")  # ends at the hang-up, not at 10 s
        assert caught.value.device == "dev-under-test" and caught.value.command == "status"
        assert link.lost and not link.alive and link.lost_reason is not None
        with pytest.raises(ConnectionLost, match="down"):
            link.write(b"x", command="move")
    assert not link.alive


def test_close_is_idempotent_and_is_not_a_loss(peer: Peer) -> None:
    link = TcpLink("127.0.0.1", peer.port, device="d")
    peer.accept()
    link.close()
    link.close()
    assert link.closed and not link.lost and not link.alive
    with pytest.raises(ConnectionLost, match="closed"):
        link.read(SHORT, command="state")


def test_a_reader_blocked_on_another_thread_is_woken_by_close(peer: Peer) -> None:
    link = TcpLink("127.0.0.1", peer.port, device="d", timeout=30)
    peer.accept()
    errors: list[BaseException] = []

    def read() -> None:
        try:
            link.read_exactly(1, time.monotonic() + 30)
        except BaseException as exc:  # noqa: BLE001 - recorded for the assertion
            errors.append(exc)

    t = threading.Thread(target=read)
    t.start()
    time.sleep(0.05)
    link.close()
    t.join(10)
    assert not t.is_alive() and isinstance(errors[0], ConnectionLost) and not link.lost


def test_exchange_feeds_the_codec_and_names_bad_bytes(peer: Peer) -> None:
    with TcpLink("127.0.0.1", peer.port, device="d") as link:
        far = peer.accept()
        lines: list[bytes] = []
        buf = bytearray()

        def feed(data: bytes) -> list[bytes]:  # a line codec: complete lines out, b"!" is not the protocol's
            buf.extend(data)
            out = []
            while b"\n" in buf:
                line, _, rest = bytes(buf).partition(b"\n")
                buf[:] = rest
                if line.startswith(b"!"):
                    raise ValueError(f"not a reply: {line!r}")
                out.append(line)
            return out

        def device() -> None:  # the reply in two pieces: the codec waits for the whole line
            lines.append(far.recv(100))
            far.sendall(b"po")
            time.sleep(0.05)
            far.sendall(b"ng\n")

        t = threading.Thread(target=device)
        t.start()
        assert list(link.exchange(b"ping\n", feed, command="ping", timeout=10)) == [b"pong"]
        t.join(10)
        assert lines == [b"ping\n"]

        far.sendall(b"!x\n")
        with pytest.raises(ProtocolError, match="not a reply") as caught:
            link.read_decoded(feed, time.monotonic() + 10, command="status")
        assert caught.value.command == "status" and not link.lost


def test_discard_input_drops_a_late_reply(peer: Peer) -> None:
    with TcpLink("127.0.0.1", peer.port, device="d") as link:
        far = peer.accept()
        far.sendall(b"late")
        deadline = time.monotonic() + 10
        while link.discard_input() == 0 and time.monotonic() < deadline:  # wait until it has arrived
            time.sleep(0.01)
        far.sendall(b"next")
        assert link.read_exactly(4, time.monotonic() + 10) == b"next"


def test_open_link_reads_the_library_s_addresses(pty: Pty, peer: Peer) -> None:
    with open_link(f"tcp://127.0.0.1:{peer.port}", timeout=0.2) as link:
        assert isinstance(link, TcpLink) and link.timeout == 0.2
    with open_link("acme+tcp://127.0.0.1?x=1", default_port=peer.port) as link:
        assert isinstance(link, TcpLink) and link.port == peer.port
    with open_link(f"serial://{pty.path}?baudrate=9600") as link:
        assert isinstance(link, SerialLink) and link.baudrate == 9600
    with open_link(pty.path, device="mine") as link:
        assert isinstance(link, SerialLink) and link.device == "mine"
    with pytest.raises(URLError):
        open_link("tcp://127.0.0.1")  # no port, no default
    with pytest.raises(URLError):
        open_link("acme+udp://127.0.0.1:5")
    with pytest.raises(ConnectionLost) as caught:
        open_link("/dev/no-such-port-here", device="gone")
    assert caught.value.command == "open" and caught.value.device == "gone"


def test_the_holder_swaps_a_broken_link_for_a_checked_fresh_one(peer: Peer) -> None:
    opened: list[TcpLink] = []
    refuse = [False]

    def connect() -> TcpLink:
        link = TcpLink("127.0.0.1", peer.port, device="d")
        opened.append(link)
        return link

    def check(link: TcpLink) -> None:
        if refuse[0]:
            raise GripperTimeout("the device does not answer yet", device="d", command="reconnect")

    holder = LinkHolder(connect, check=check)
    far = peer.accept()
    first = holder.link
    assert holder.alive and holder.reconnect() is not first  # not reuse_alive: always a fresh link
    assert first.closed
    second = holder.link
    peer.accept()

    far.close()
    refuse[0] = True
    with pytest.raises(GripperTimeout):
        holder.reconnect()
    peer.accept()
    assert opened[-1].closed and holder.link is second  # the fresh one that failed its check: closed
    refuse[0] = False
    third = holder.reconnect()
    peer.accept()
    assert third is opened[-1] and third.alive and second.closed

    keeper = LinkHolder(connect, check=check, link=third, reuse_alive=True)
    assert keeper.reconnect() is third  # a link that never broke is kept once the device answers on it
    holder.close()
    assert not holder.alive and third.closed
    with pytest.raises(ConnectionLost):
        holder.reconnect()
