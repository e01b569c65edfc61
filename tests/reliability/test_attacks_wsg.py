"""Issue 13 (the WSG client) and issue 12 §4 (the WSG simulator), attacked as an attacker would.

Each test reproduces one report and fails on the code before the fix: Ctrl-C at random moments, late and
duplicated replies, a hostile TCP proxy that splits replies or injects false headers, datagrams from many
source ports, CAN identifiers a frame format cannot carry. Simulators on real loopback transports only.
"""

from __future__ import annotations

import random
import signal
import socket
import threading
import time
from collections.abc import Callable, Iterator

import pytest

from grippers.drivers.errors import GripperTimeout
from grippers.drivers.wsg.client import WsgClient
from grippers.drivers.wsg.commands import Cmd, SystemFlags, decode_reply, encode_request
from grippers.drivers.wsg.protocol import Packet, PacketParser, encode_packet
from grippers.drivers.wsg.sim import WsgModel, serve


def _wait_for(predicate: Callable[[], bool], timeout: float = 3.0) -> bool:
    deadline = time.monotonic() + timeout
    while not predicate():
        if time.monotonic() >= deadline:
            return False
        time.sleep(0.01)
    return True


# ------------------------------------------------------------------------------------- 1. Ctrl-C


@pytest.mark.parametrize("scheme", ["tcp", "udp"])
def test_ctrl_c_at_random_moments_never_wedges_a_command(wsg_sim, wsg_connect, scheme) -> None:
    """Issue 13 item 1: SIGINT 1-40 ms into a loop of state() calls; every later state() must work.

    Before the fix, an interrupt that came after the reply was read threw the bytes away and left the
    exchange registered: every later state() raised "still outstanding", for the life of the connection.
    """
    server = wsg_sim(f"{scheme}://127.0.0.1:0")
    c = wsg_connect(server.url, timeout=1.0, stale_ttl=0.3)
    rng = random.Random(13)
    main = threading.main_thread().ident
    assert main == threading.get_ident()
    previous = signal.signal(signal.SIGINT, signal.default_int_handler)
    interrupted = 0
    try:
        for _ in range(30):
            timer = threading.Timer(rng.uniform(0.001, 0.040), signal.pthread_kill, (main, signal.SIGINT))
            try:
                timer.start()
                while True:
                    c.system_state()
            except KeyboardInterrupt:
                interrupted += 1
            timer.join()
            # At once for another id, and for the same id as soon as its reply is accounted for.
            assert c.loop(b"alive", timeout=2.0) == b"alive"
            assert isinstance(c.system_state(timeout=2.0), SystemFlags)
    finally:
        signal.signal(signal.SIGINT, previous)
    assert interrupted == 30
    assert c.connection_lost is None


def test_stop_goes_out_at_once_from_a_ctrl_c_handler_and_the_motion_reports_aborted(
    wsg_sim, wsg_connect
) -> None:
    """Issue 12 §3 (WSG): Ctrl-C during a blocking motion, STOP from the handler; a motion stopped from
    another thread ends with E_CMD_ABORTED, never as done."""
    server = wsg_sim("tcp://127.0.0.1:0", time_scale=5.0)
    c = wsg_connect(server.url, timeout=1.0)
    c.home()
    main = threading.main_thread().ident
    previous = signal.signal(signal.SIGINT, signal.default_int_handler)
    try:
        timer = threading.Timer(0.05, signal.pthread_kill, (main, signal.SIGINT))
        timer.start()
        with pytest.raises(KeyboardInterrupt):
            try:
                c.preposition(0.0, 5.0)  # ~20 s of travel at this speed
            except KeyboardInterrupt:
                t0 = time.monotonic()
                c.stop()  # the abandoned motion's slot does not delay STOP
                assert time.monotonic() - t0 < 0.5
                raise
        timer.join()
    finally:
        signal.signal(signal.SIGINT, previous)
    assert _wait_for(lambda: not c.system_state() & SystemFlags.SF_MOVING)
    # The motion's final reply (E_CMD_ABORTED) went to its stale marker; the next motion works.
    assert _wait_for(lambda: c.stats["stale_replies"] >= 1)
    pending = c.preposition(50.0, 400.0, wait=False)
    threading.Timer(0.01, c.stop).start()
    with pytest.raises(Exception) as info:
        pending.result(timeout=5.0)
    assert "E_CMD_ABORTED" in str(info.value)


# ------------------------------------------------------------------------------ 2. stray replies


def test_a_reply_seconds_late_is_never_handed_to_a_later_loop(wsg_sim, wsg_connect) -> None:
    """Issue 13 item 2: loop(A) times out, its reply comes 1 s later (after the old 2 s-style TTL, here
    0.3 s); loop(B) must return B and every later loop its own data."""
    server = wsg_sim("tcp://127.0.0.1:0")
    c = wsg_connect(server.url, timeout=0.2, stale_ttl=0.3)
    server.faults.delay_replies(1.0)
    with pytest.raises(GripperTimeout):
        c.loop(b"A")
    time.sleep(1.2)
    for data in (b"B", b"C", b"D"):
        assert c.loop(data) == data
    assert c.stats["stale_replies"] + c.stats["unsolicited"] == 1


def test_a_settings_read_never_returns_an_older_value_after_a_late_reply(wsg_sim, wsg_connect) -> None:
    server = wsg_sim("tcp://127.0.0.1:0")
    c = wsg_connect(server.url, timeout=0.2, stale_ttl=0.3)
    c.set_force_limit(10.0)
    server.faults.delay_replies(1.0)
    with pytest.raises(GripperTimeout):
        c.force_limit()
    c.set_force_limit(20.0)
    time.sleep(1.2)
    assert c.force_limit() == pytest.approx(20.0)
    assert c.force_limit() == pytest.approx(20.0)


def test_a_lost_reply_is_proved_lost_by_a_loop_barrier(wsg_sim, wsg_connect) -> None:
    server = wsg_sim("udp://127.0.0.1:0")
    c = wsg_connect(server.url, timeout=0.2, stale_ttl=0.2)
    server.faults.drop_replies(1)
    with pytest.raises(GripperTimeout):
        c.acceleration()
    time.sleep(0.3)
    assert c.acceleration() > 0  # nothing else was sent: the client proved the reply lost itself
    assert c.stats["barriers"] == 1 and c.stats["lost_replies"] == 1


def test_a_duplicated_reply_is_consumed_not_matched_to_the_next_request(wsg_sim, wsg_connect) -> None:
    """Issue 13 item 2: one duplicated reply made every later loop return the previous one's data, and a
    settings read return a value another program had already changed."""
    server = wsg_sim("tcp://127.0.0.1:0")
    c = wsg_connect(server.url)
    other = wsg_connect(server.url)
    server.faults.duplicate_replies(1)
    assert c.loop(b"one") == b"one"
    for data in (b"two", b"three", b"four"):
        assert c.loop(data) == data
    c.set_force_limit(10.0)
    server.faults.duplicate_replies(1)
    assert c.force_limit() == pytest.approx(10.0)
    time.sleep(0.05)  # the duplicate has arrived
    other.set_force_limit(30.0)
    assert c.force_limit() == pytest.approx(30.0)
    assert c.stats["unsolicited"] + c.stats["stale_replies"] == 2


# ------------------------------------------------------------------------ a hostile TCP proxy


class _Proxy:
    """A TCP proxy on loopback between a client and a simulator that can misbehave on the way back."""

    def __init__(self, upstream: tuple[str, int], *, split_gap: float = 0.0) -> None:
        self.split_gap = split_gap
        self.inject = bytearray()
        self._upstream = upstream
        self._listener = socket.create_server(("127.0.0.1", 0))
        self.port = self._listener.getsockname()[1]
        self._socks: list[socket.socket] = [self._listener]
        self._thread = threading.Thread(target=self._serve, daemon=True)
        self._thread.start()

    def _serve(self) -> None:
        try:
            client, _ = self._listener.accept()
        except OSError:
            return
        server = socket.create_connection(self._upstream)
        for s in (client, server):
            s.setsockopt(socket.IPPROTO_TCP, socket.TCP_NODELAY, 1)
        self._socks += [client, server]
        threading.Thread(target=self._pump, args=(client, server, False), daemon=True).start()
        self._pump(server, client, True)

    def _pump(self, src: socket.socket, dst: socket.socket, replies: bool) -> None:
        try:
            while data := src.recv(65536):
                if replies and self.inject:
                    dst.sendall(bytes(self.inject))
                    self.inject.clear()
                if replies and self.split_gap and len(data) > 1:
                    half = len(data) // 2
                    dst.sendall(data[:half])
                    time.sleep(self.split_gap)
                    data = data[half:]
                dst.sendall(data)
        except OSError:
            pass

    def close(self) -> None:
        for s in self._socks:
            try:
                s.shutdown(socket.SHUT_RDWR)
            except OSError:
                pass
            s.close()


@pytest.fixture
def proxy() -> Iterator[Callable[..., _Proxy]]:
    made: list[_Proxy] = []

    def make(url: str, **kw) -> _Proxy:
        host, port = url.split("//")[1].split(":")
        p = _Proxy((host, int(port)), **kw)
        made.append(p)
        return p

    yield make
    for p in made:
        p.close()


def test_tcp_reply_split_in_two_segments_60_ms_apart_is_reassembled(wsg_sim, wsg_connect, proxy) -> None:
    """Issue 13 item 3: the serial silent-gap rule applied to TCP discarded the first half."""
    server = wsg_sim("tcp://127.0.0.1:0")
    p = proxy(server.url, split_gap=0.06)
    c = wsg_connect(f"wsg+tcp://127.0.0.1:{p.port}", timeout=1.0)
    assert c.loop(b"split") == b"split"
    assert c.system_state() & SystemFlags.SF_FAST_STOP == 0
    assert c.stats["discarded_bytes"] == 0


def test_false_header_during_10_ms_updates_is_dropped_at_once(wsg_sim, wsg_connect, proxy) -> None:
    """Issue 13 item 4: a header claiming 1,000 bytes held the updates behind it back for 0.7 s (the size
    field was believed up to 1,024 bytes for every id); the next call timed out."""
    server = wsg_sim("tcp://127.0.0.1:0", time_scale=1.0)
    p = proxy(server.url)
    c = wsg_connect(f"wsg+tcp://127.0.0.1:{p.port}", timeout=0.3)
    sub = c.subscribe(Cmd.GET_WIDTH, period_ms=10, iter_timeout=1.0)
    for claimed in (0x43, 0x40, 0x63):  # subscribed; fixed-size; open-ended but not expected
        p.inject += b"\xaa\xaa\xaa" + bytes([claimed]) + (1000).to_bytes(2, "little")
        assert c.system_state() & SystemFlags.SF_FAST_STOP == 0  # within 0.3 s
    before = sub.received
    assert _wait_for(lambda: sub.received >= before + 5, timeout=1.0)
    assert c.stats["bad_lengths"] == 3
    sub.close()


# ----------------------------------------------------------------------- 10. UDP exposure


def test_udp_client_binds_the_address_that_reaches_the_gripper(wsg_sim, wsg_connect) -> None:
    server = wsg_sim("udp://127.0.0.1:0")
    c = wsg_connect(server.url)
    assert c.transport.local_address[0] == "127.0.0.1"  # was 0.0.0.0: every interface
    assert c.loop(b"x") == b"x"


# -------------------------------------------------------------------------- 9. UDP simulator memory


def test_udp_simulator_forgets_peers_beyond_its_bound(wsg_sim) -> None:
    server = wsg_sim("udp://127.0.0.1:0")
    host, port = server.address
    request = encode_packet(Cmd.LOOP, b"hi")
    for _ in range(3):
        socks = [socket.socket(socket.AF_INET, socket.SOCK_DGRAM) for _ in range(50)]
        for s in socks:
            s.bind(("127.0.0.1", 0))
            s.settimeout(2.0)
            s.sendto(request, (host, port))
        for s in socks:
            assert s.recv(100) == encode_packet(Cmd.LOOP, b"\x00\x00hi")
            s.close()
    assert server.peers <= server.max_peers == 64
    with server.lock:
        assert len(server.model._connections) <= 64 + 1  # and the model's own connection 0


# ----------------------------------------------------------------- issue 12 §4: simulator input


def _wire_request(sock: socket.socket, packet: bytes, pieces: int, pause: float) -> Packet:
    step = max(1, len(packet) // pieces)
    for i in range(0, len(packet), step):
        sock.sendall(packet[i : i + step])
        time.sleep(pause)
    parser = PacketParser()
    sock.settimeout(2.0)
    while True:
        items = [x for x in parser.feed(sock.recv(4096)) if isinstance(x, Packet)]
        if items:
            return items[0]


def test_tcp_simulator_reassembles_a_request_written_in_pieces_with_pauses(wsg_sim) -> None:
    server = wsg_sim("tcp://127.0.0.1:0")
    with socket.create_connection(server.address) as sock:
        sock.setsockopt(socket.IPPROTO_TCP, socket.TCP_NODELAY, 1)
        packet = _wire_request(sock, encode_packet(Cmd.LOOP, b"pieces"), pieces=3, pause=0.06)
        assert decode_reply(packet.command, packet.payload).fields["data"] == b"pieces"
        sock.sendall(encode_packet(Cmd.DISCONNECT))


def test_simulator_refuses_auto_update_periods_below_10_ms(wsg_sim, wsg_connect) -> None:
    server = wsg_sim("tcp://127.0.0.1:0")
    c = wsg_connect(server.url)
    payload = encode_request(Cmd.GET_WIDTH, auto_update=True, period_ms=5)
    assert c.request(Cmd.GET_WIDTH, payload).status == 15  # E_CMD_FORMAT_ERROR (WSG manual 4.0.x §3.4.4)


def test_can_simulator_refuses_ids_its_frame_format_cannot_carry() -> None:
    channel = f"wsg-ids-{time.monotonic_ns()}"
    with pytest.raises(ValueError, match=r"recv_id 0x800 is not valid for a standard \(11-bit\)"):
        serve(WsgModel(), f"can://virtual/{channel}?recv_id=0x800")
    with pytest.raises(ValueError, match="send_id"):
        serve(WsgModel(), f"can://virtual/{channel}?send_id=-1")
    server = serve(WsgModel(), f"can://virtual/{channel}?recv_id=0x800&extended=1", time_scale=50.0)
    try:
        assert server.url.endswith("extended=1")
        with WsgClient.from_url(server.url, timeout=1.0) as c:
            assert c.loop(b"ext") == b"ext"
    finally:
        server.close()
    assert server.error is None


# ------------------------------------------------------------------------- issue 15: FAST STOP


def test_tcp_connection_closed_without_07h_leaves_fast_stop_for_the_next_connection(wsg_sim) -> None:
    server = wsg_sim("tcp://127.0.0.1:0")
    with WsgClient.from_url(server.url, timeout=1.0) as first:
        first.home()
        first.transport.close()  # the process dies: no 07h
    with WsgClient.from_url(server.url, timeout=1.0) as second:
        assert _wait_for(lambda: bool(second.system_state() & SystemFlags.SF_FAST_STOP))
        second.acknowledge_fast_stop()
        assert not second.system_state() & SystemFlags.SF_FAST_STOP
    with WsgClient.from_url(server.url, timeout=1.0) as third:  # closed with 07h above: no FAST STOP
        assert not third.system_state() & SystemFlags.SF_FAST_STOP
