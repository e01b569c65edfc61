"""WsgClient against the WSG simulator over real transports: TCP, UDP, a pty and python-can virtual."""

from __future__ import annotations

import threading
import time

import can
import pytest

from grippers.drivers.errors import (
    CommandFailed,
    ConnectionLost,
    GripperError,
    GripperTimeout,
    LimitError,
    NotSupported,
    ProtocolError,
)
from grippers.drivers.wsg.client import WsgClient
from grippers.drivers.wsg.commands import Cmd, FirmwareVersion, GraspingState, SystemFlags
from grippers.drivers.wsg.protocol import PacketParser, Status, decode_packet, encode_packet
from grippers.drivers.wsg.transports import TcpTransport

pytest.importorskip("grippers.drivers.wsg.sim")

TRANSPORTS = ["tcp", "udp", "pty", "can"]


def _listen(kind: str, channel: str) -> str:
    return {
        "tcp": "tcp://127.0.0.1:0",
        "udp": "udp://127.0.0.1:0",
        "pty": "pty",
        "can": f"can://virtual/{channel}",
    }[kind]


@pytest.fixture
def connect(wsg_sim, wsg_client_factory, can_channel):
    """``connect(kind, **model_kw) -> (server, client)``."""

    def start(kind: str = "tcp", *, client_kw: dict | None = None, **model_kw):
        server = wsg_sim(_listen(kind, can_channel), **model_kw)
        client = wsg_client_factory(server.url, **(client_kw or {}))
        return server, client

    return start


@pytest.mark.parametrize("kind", TRANSPORTS)
def test_home_move_grip_release_and_read_state(connect, kind) -> None:
    server, c = connect(kind, part_width_mm=30.0)
    info = c.system_info()
    assert c.firmware == info.firmware == FirmwareVersion(4, 0, 1)
    assert c.system_limits().stroke == pytest.approx(110.0)
    assert not c.system_state() & SystemFlags.SF_REFERENCED
    c.home()
    assert c.system_state() & SystemFlags.SF_REFERENCED
    c.preposition(60.0, 200.0)
    assert c.width() == pytest.approx(60.0, abs=0.05)
    c.grip(28.0, 100.0, force=40.0)  # the part (30 mm) lies within the clamping travel
    assert c.grasping_state() is GraspingState.HOLDING
    assert c.force_limit() == pytest.approx(40.0)
    assert c.width() == pytest.approx(30.0, abs=0.5)
    c.release(70.0, 200.0)
    assert c.grasping_state() is GraspingState.IDLE
    assert c.width() == pytest.approx(70.0, abs=0.05)
    assert c.temperature() == pytest.approx(31.5)
    assert c.loop(b"\xaa\xaa\xaa\x00") == b"\xaa\xaa\xaa\x00"
    c.set_device_tag("cell 7")
    assert c.device_tag() == "cell 7"
    assert c.grasping_statistics().total == 1


def test_state_queries_and_several_threads_while_a_motion_is_pending(connect) -> None:
    server, c = connect("tcp")
    c.home()
    pending = c.preposition(5.0, 5.0, wait=False)  # 105 mm at 5 mm/s: ~0.4 s wall at time scale 50
    assert not pending.done()
    errors: list[BaseException] = []
    widths: list[float] = []

    def poll() -> None:
        try:
            for _ in range(10):
                widths.append(c.width())
                assert c.system_state() & SystemFlags.SF_MOVING or pending.done()
                c.speed()
        except BaseException as exc:  # noqa: BLE001 - collected for the assertion below
            errors.append(exc)

    threads = [threading.Thread(target=poll) for _ in range(6)]
    for t in threads:
        t.start()
    for t in threads:
        t.join(10)
    assert errors == []
    assert len(widths) == 60 and min(widths) < max(widths)  # the fingers moved while we read
    pending.result(timeout=10)
    assert pending.done()
    assert c.width() == pytest.approx(5.0, abs=0.05)


def test_device_status_raises_command_failed(connect) -> None:
    server, c = connect("tcp")
    with pytest.raises(CommandFailed) as info:
        c.preposition(10.0, 50.0)  # not referenced yet
    err = info.value
    assert err.status == Status.E_NOT_INITIALIZED and err.status_name == "E_NOT_INITIALIZED"
    assert err.command == "PREPOSITION (21h)" and err.device == c.device
    with pytest.raises(CommandFailed) as info:
        c.soft_limits()
    assert info.value.status == Status.E_NOT_AVAILABLE
    with pytest.raises(CommandFailed) as info:
        c.grip(10.0, 50.0)  # no part configured: E_CMD_FAILED after homing
    assert info.value.status in (Status.E_NOT_INITIALIZED, Status.E_CMD_FAILED)
    raw = c.request(0x21, b"\x00")  # raw requests return the packet, any status
    assert raw.status == Status.E_CMD_FORMAT_ERROR
    with pytest.raises(CommandFailed):
        c.request(0x21, b"\x00", check=True)


def test_values_are_refused_before_sending(connect) -> None:
    server, c = connect("tcp")
    for call in (
        lambda: c.preposition(float("nan"), 10.0),
        lambda: c.preposition(10.0, 0.0),
        lambda: c.grip(-1.0, 10.0),
        lambda: c.home(3),
        lambda: c.set_device_tag("x" * 65),
        lambda: c.set_device_tag("bad\ttag"),
        lambda: c.subscribe(Cmd.GET_WIDTH, period_ms=5),
        lambda: c.finger_info(3),
        lambda: c.set_soft_limits(50.0, 10.0),
        lambda: c.loop(bytes(257)),
    ):
        with pytest.raises(LimitError):
            call()
    with pytest.raises(NotSupported):
        c.subscribe(Cmd.GET_TEMPERATURE)
    assert c.stats["unsolicited"] == 0


def test_firmware_2_capabilities_are_refused_locally(connect) -> None:
    server, c = connect("tcp", firmware="2.2.0")
    with pytest.raises(CommandFailed) as info:  # before 50h the device itself says no
        c.temperature()
    assert info.value.status == Status.E_CMD_UNKNOWN
    assert str(c.system_info().firmware) == "2.2.0"
    for call in (
        c.temperature,
        lambda: c.finger_info(1),
        lambda: c.finger_power(2, True),
        lambda: c.request(0x63),
    ):
        with pytest.raises(NotSupported):
            call()
    assert c.width() == 0.0  # the rest still works


def test_finger_power_pends_then_succeeds(connect) -> None:
    server, c = connect("tcp")
    c.finger_power(1, False)
    c.finger_power(1, True)
    assert c.finger_flags(1) & 1  # POWER_ON


def test_close_announces_the_disconnect_so_no_fast_stop(connect, wsg_client_factory) -> None:
    server, c = connect("tcp")
    c.home()
    c.close()
    c.close()  # idempotent
    assert c.closed
    with pytest.raises(ConnectionLost):
        c.width()
    again = wsg_client_factory(server.url)
    assert not again.system_state() & SystemFlags.SF_FAST_STOP


def test_dropped_tcp_connection_means_fast_stop_until_acknowledged(wsg_sim, wsg_client_factory) -> None:
    server = wsg_sim("tcp://127.0.0.1:0")
    host, port = server.url.split("//")[1].split(":")
    raw = TcpTransport(host, int(port))
    raw.send(encode_packet(0x50))
    deadline = time.monotonic() + 5
    parser = PacketParser()
    while not (got := parser.feed(raw.recv(0.1))) and time.monotonic() < deadline:
        pass
    assert got and got[0].status == Status.E_SUCCESS
    raw.close()  # no 07h: the gripper enters FAST STOP (WSG manual 4.0.x §1.4.2)
    c = wsg_client_factory(server.url)
    deadline = time.monotonic() + 5
    while not c.system_state() & SystemFlags.SF_FAST_STOP and time.monotonic() < deadline:
        time.sleep(0.01)
    assert c.system_state() & SystemFlags.SF_FAST_STOP
    with pytest.raises(CommandFailed) as info:
        c.home()
    assert info.value.status == Status.E_ACCESS_DENIED
    with pytest.raises(CommandFailed) as info:
        c.acknowledge_fast_stop(b"ok!")
    assert info.value.status == Status.E_CMD_FORMAT_ERROR
    c.acknowledge_fast_stop()
    assert not c.system_state() & SystemFlags.SF_FAST_STOP
    c.fast_stop()
    assert c.system_state() & SystemFlags.SF_FAST_STOP
    c.acknowledge_fast_stop()


def test_lost_connection_releases_every_waiter_with_connection_lost(connect) -> None:
    server, c = connect("tcp")
    c.home()
    pending = c.preposition(5.0, 5.0, wait=False)
    server.faults.request_close()
    with pytest.raises(ConnectionLost) as info:
        pending.result(timeout=5)
    assert isinstance(info.value, ConnectionError)
    with pytest.raises(ConnectionLost):
        c.width()
    assert c.connection_lost is not None
    c.close()  # still fine after the loss


def test_pty_closed_by_the_device_is_a_lost_connection(connect) -> None:
    server, c = connect("pty")
    assert c.width() == 0.0
    server.close()
    deadline = time.monotonic() + 5
    while c.connection_lost is None and time.monotonic() < deadline:
        time.sleep(0.01)
    with pytest.raises((ConnectionLost, GripperTimeout)):
        c.width(timeout=0.5)


def test_timeout_and_a_late_reply_is_never_matched_to_the_next_command(connect) -> None:
    server, c = connect("tcp")
    c.home()  # width 110 mm
    server.faults.delay_replies(0.4)
    with pytest.raises(GripperTimeout) as info:
        c.width(timeout=0.1)
    assert isinstance(info.value, TimeoutError)
    c.preposition(50.0, 420.0)
    # The delayed reply still says 110 mm; it must go to the abandoned request, not to this one.
    assert c.width(timeout=2.0) == pytest.approx(50.0, abs=0.05)
    assert c.stats["stale_replies"] == 1


def test_a_lost_reply_frees_its_command_after_the_stale_ttl(connect) -> None:
    server, c = connect("udp", client_kw={"stale_ttl": 0.2})
    server.faults.drop_replies(1)
    with pytest.raises(GripperTimeout):
        c.system_state(timeout=0.2)
    assert c.system_state(timeout=2.0) == SystemFlags(0)


def test_motion_timeout_keeps_the_late_final_reply_away(connect) -> None:
    server, c = connect("tcp")
    c.home()
    with pytest.raises(GripperTimeout):
        c.preposition(5.0, 5.0, timeout=0.1)  # needs ~0.4 s wall
    c.stop()
    pending = c.preposition(100.0, 420.0, wait=False)  # waits until the first motion's final reply arrived
    pending.result(timeout=5)
    assert c.width() == pytest.approx(100.0, abs=0.05)


def test_cancel_stops_a_pending_motion(connect) -> None:
    server, c = connect("tcp")
    c.home()
    pending = c.preposition(5.0, 5.0, wait=False)
    pending.cancel()
    with pytest.raises(CommandFailed) as info:
        pending.result(timeout=5)
    assert info.value.status == Status.E_CMD_ABORTED
    assert c.system_state() & SystemFlags.SF_AXIS_STOPPED


def test_garbage_and_corruption_never_kill_the_reader(connect) -> None:
    server, c = connect("tcp")
    server.faults.send_garbage(b"\xaa\x00\xaa\xaa\xaa\x43\x30\x00junk\xaa\xaa")
    assert c.width(timeout=2.0) == 0.0
    server.faults.corrupt_replies(1)
    with pytest.raises(ProtocolError):
        c.acceleration()
    assert c.acceleration() > 0
    server.faults.send_garbage(b"\xaa\xaa\xaa\x40\xff\xff")  # impossible length
    assert c.system_state() == SystemFlags(0)
    assert c.stats["checksum_errors"] >= 1 and c.stats["discarded_bytes"] > 0


def test_subscription_callbacks_and_iterator(connect) -> None:
    server, c = connect("tcp")
    c.home()
    seen: list[float] = []
    # iter_timeout: a missed update fails the test instead of hanging it.
    sub = c.subscribe(Cmd.GET_WIDTH, period_ms=500, changes_only=True, callback=seen.append, iter_timeout=5.0)
    assert sub.get(timeout=2) == pytest.approx(110.0)  # the immediate reply
    values = []
    for target in (60.0, 70.0):
        c.preposition(target, 420.0)
        for value in sub:
            values.append(value)
            if value == pytest.approx(target, abs=0.05):
                break
        # A state query of the same id while subscribed keeps the subscription running (the next motion's
        # updates still come). Asked before the update, its reply may take the update's place (changes only:
        # the device then has nothing new to send), so it is asked after.
        assert c.width() == pytest.approx(target, abs=0.05)
    assert values and seen[: len(values) + 1]
    assert all(a != b for a, b in zip(seen, seen[1:], strict=False))  # changes only
    sub.close()
    count = len(seen)
    time.sleep(0.05)
    c.preposition(80.0, 420.0)
    assert len(seen) == count and list(sub) == []
    with pytest.raises(GripperError):
        sub.get(timeout=0.1)


def test_subscription_queue_drops_the_oldest(connect) -> None:
    server, c = connect("tcp")
    sub = c.subscribe(Cmd.GET_SYSTEM_STATE, period_ms=10, maxsize=3)
    deadline = time.monotonic() + 5
    while sub.dropped == 0 and time.monotonic() < deadline:
        time.sleep(0.01)
    assert sub.dropped > 0 and sub.received > 3
    assert [sub.get(timeout=1) for _ in range(3)]
    sub.close()


def test_callback_cannot_deadlock_the_reader(connect) -> None:
    server, c = connect("tcp")
    errors: list[BaseException] = []

    def bad(_value: object) -> None:
        try:
            c.width()
        except GripperError as exc:
            errors.append(exc)

    sub = c.subscribe(Cmd.GET_GRASPING_STATE, period_ms=10, callback=bad)
    deadline = time.monotonic() + 5
    while len(errors) < 2 and time.monotonic() < deadline:
        time.sleep(0.01)
    assert len(errors) >= 2 and "callback" in str(errors[-1])
    sub.close()
    assert c.width() == 0.0


def test_close_joins_the_reader_and_ends_subscriptions(connect) -> None:
    server, c = connect("udp")
    sub = c.subscribe(Cmd.GET_FORCE, period_ms=50)
    (reader,) = [t for t in threading.enumerate() if t.name == f"{c.device} reader"]
    c.close()
    assert not reader.is_alive()
    assert sub.closed
    assert all(v == 0.0 for v in sub)  # drains what was queued, then ends
    with c:  # the context manager on a closed client is harmless
        pass
    assert c.closed


def test_can_frames_on_the_bus(wsg_sim, can_channel) -> None:
    wsg_sim(f"can://virtual/{can_channel}?send_id=0x10&recv_id=0x11")
    sniffer = can.Bus(interface="virtual", channel=can_channel)
    try:
        with WsgClient.can(interface="virtual", channel=can_channel, send_id=0x10, recv_id=0x11) as c:
            c.set_soft_limits(1.0, 100.0)  # 8-byte payload: a 16-byte packet, two full frames
            frames = []
            deadline = time.monotonic() + 2
            while len(frames) < 4 and time.monotonic() < deadline:
                msg = sniffer.recv(0.1)
                if msg is not None:
                    frames.append(msg)
        requests = [m for m in frames if m.arbitration_id == 0x10]
        assert [len(m.data) for m in requests] == [8, 8]
        assert decode_packet(b"".join(bytes(m.data) for m in requests)).command == 0x34
        assert all(m.arbitration_id in (0x10, 0x11) and not m.is_extended_id for m in frames)
    finally:
        sniffer.shutdown()


def test_serial_framing_options_over_loop_url() -> None:
    # pyserial's loop:// echoes what is written: a raw request comes back as its own "reply" (not LOOP,
    # whose reply must echo the request's data after a status).
    with WsgClient.serial("loop://", baudrate=9600, parity="E", stopbits=2) as c:
        packet = c.request(Cmd.GET_WIDTH, b"\x00\x00\x00")
        assert packet.payload == b"\x00\x00\x00"
        assert c.transport.framing["parity"] == "E" and c.transport.framing["stopbits"] == 2


def test_url_factories_refuse_unknown_schemes() -> None:
    with pytest.raises(LimitError):
        WsgClient.from_url("http://example.com")
    with pytest.raises(ConnectionLost):
        WsgClient.tcp("127.0.0.1", 1, connect_timeout=1.0)


class _InterruptedOnce(TcpTransport):
    """A real TCP line whose next send or receive is interrupted by Ctrl-C (KeyboardInterrupt), once."""

    def __init__(self, host: str, port: int, where: str) -> None:
        super().__init__(host, port)
        self.where: str | None = where

    def send(self, data: bytes) -> None:
        if self.where == "send":
            self.where = None
            raise KeyboardInterrupt
        super().send(data)

    def recv(self, timeout: float) -> bytes:
        if self.where == "recv":
            self.where = None
            raise KeyboardInterrupt
        return super().recv(timeout)


@pytest.mark.parametrize("where", ["send", "recv"])
def test_ctrl_c_during_an_exchange_leaves_the_client_usable(wsg_sim, where) -> None:
    """An interrupted caller gives back the reading role at once; its command id is free again once its
    possible reply is accounted for (read, or its stale marker expired)."""
    server = wsg_sim("tcp://127.0.0.1:0")
    host, port = server.url.split("//")[1].split(":")
    c = WsgClient(_InterruptedOnce(host, int(port), where), stale_ttl=0.3)
    try:
        with pytest.raises(KeyboardInterrupt):
            c.width()
        t0 = time.monotonic()
        assert not c.system_state() & SystemFlags.SF_FAST_STOP  # another id: no wait for a reader role
        assert time.monotonic() - t0 < 0.25
        assert c.width() == pytest.approx(0.0)  # the same id, within the default timeout
        assert c.stats["unsolicited"] == 0
    finally:
        c.close()
