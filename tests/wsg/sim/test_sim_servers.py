"""The simulator served over real transports: TCP, UDP, a pseudo-terminal and python-can buses."""

from __future__ import annotations

import os
import socket
import time

import can
import pytest

from grippers.drivers.wsg.commands import Cmd, GraspingState, SystemFlags, encode_request
from grippers.drivers.wsg.protocol import ChecksumError, Packet, Status, encode_packet
from grippers.drivers.wsg.sim import WsgModel, serve

S = Status


def _basic_session(wire) -> None:
    """Home, move, grip (a 40 mm part), read state, release: the same on every transport."""
    assert wire.request(Cmd.PREPOSITION, width=10.0, speed=100.0).status == S.E_NOT_INITIALIZED
    assert wire.run(Cmd.HOMING).ok
    assert wire.request(Cmd.GET_WIDTH).fields["width"] == pytest.approx(110.0)
    assert wire.run(Cmd.PREPOSITION, width=60.0, speed=200.0).ok
    assert wire.run(Cmd.GRIP, width=40.0, speed=100.0).ok
    assert wire.request(Cmd.GET_GRASPING_STATE).fields["state"] == GraspingState.HOLDING
    assert wire.request(Cmd.GET_FORCE).fields["force"] > 0
    assert wire.run(Cmd.RELEASE, width=70.0, speed=100.0).ok
    assert wire.request(Cmd.GET_SYSTEM_STATE).fields["state"] & SystemFlags.SF_REFERENCED


@pytest.mark.parametrize("listen", ["tcp://127.0.0.1:0", "udp://127.0.0.1:0", "pty"])
def test_transport_answers(start_server, open_wire, listen: str) -> None:
    server = start_server(listen, part_width_mm=40.0)
    _basic_session(open_wire(server.url))


def test_can_virtual_bus(start_server, open_wire, can_channel: str) -> None:
    server = start_server(f"can://virtual/{can_channel}", part_width_mm=40.0)
    assert server.url == f"wsg+can://virtual/{can_channel}"
    wire = open_wire(server.url)
    _basic_session(wire)
    assert wire.frames and all(len(f.data) <= 8 and f.arbitration_id == 0x001 for f in wire.frames)
    # 53h's reply is 8 + 34 = 42 bytes: five full frames and a short one
    wire.frames.clear()
    assert wire.request(Cmd.GET_SYSTEM_LIMITS).ok
    assert [len(f.data) for f in wire.frames] == [8, 8, 8, 8, 8, 2]


def test_can_custom_ids(start_server, open_wire, can_channel: str) -> None:
    server = start_server(f"can://virtual/{can_channel}?send_id=0x120&recv_id=0x121")
    assert server.url.endswith("?send_id=0x120&recv_id=0x121")
    wire = open_wire(server.url)
    assert wire.request(Cmd.LOOP, data=b"hello").fields["data"] == b"hello"
    assert {f.arbitration_id for f in wire.frames} == {0x121}


def test_can_udp_multicast_bus(start_server, open_wire) -> None:
    # docs/protocols.md §2 (testing without CAN hardware): every udp_multicast bus sees all traffic on the
    # host, so this test isolates itself by ids, not by the group.
    send_id = 0x400 + (os.getpid() % 0x100) * 2
    listen = f"can://udp_multicast/239.74.163.2?send_id={send_id:#x}&recv_id={send_id + 1:#x}"
    try:
        server = start_server(listen)
    except (can.CanError, OSError) as exc:
        pytest.skip(f"python-can udp_multicast unavailable here: {exc}")
    wire = open_wire(server.url)
    assert wire.request(Cmd.LOOP, data=b"multicast").fields["data"] == b"multicast"
    assert wire.run(Cmd.HOMING).ok


def test_can_lent_bus_is_not_shut_down(can_channel: str) -> None:
    bus = can.Bus(interface="virtual", channel=can_channel)
    try:
        server = serve(WsgModel(), f"can://virtual/{can_channel}", time_scale=50.0, bus=bus)
        server.close()
        bus.send(can.Message(arbitration_id=5, data=b"x", is_extended_id=False))  # still usable
    finally:
        bus.shutdown()


def test_can_packet_of_exactly_16_bytes_ends_on_a_full_frame(start_server, open_wire, can_channel) -> None:
    server = start_server(f"can://virtual/{can_channel}")
    wire = open_wire(server.url)
    # loop with 6 bytes: request 8 + 6 = 14; reply 8 + 2 + 6 = 16 bytes -> two full frames
    assert wire.request(Cmd.LOOP, data=b"abcdef").fields["data"] == b"abcdef"
    assert [len(f.data) for f in wire.frames] == [8, 8]


# ---------------------------------------------------------------------------------------------------- TCP


def test_tcp_several_connections_and_state_during_motion(start_server, open_wire) -> None:
    server = start_server("tcp://127.0.0.1:0", time_scale=5.0)
    a, b = open_wire(server.url), open_wire(server.url)
    assert a.run(Cmd.HOMING, timeout=5.0).ok
    assert a.request(Cmd.PREPOSITION, width=0.0, speed=50.0).pending  # 2.2 s device time
    widths = [b.request(Cmd.GET_WIDTH).fields["width"] for _ in range(3)]
    assert all(0.0 < w <= 110.0 for w in widths)
    assert b.request(Cmd.GET_SYSTEM_STATE).fields["state"] & SystemFlags.SF_MOVING
    assert b.request(Cmd.PREPOSITION, width=5.0, speed=50.0).status == S.E_ALREADY_RUNNING
    assert b.request(Cmd.STOP).ok
    assert a.expect(Cmd.PREPOSITION).status == S.E_CMD_ABORTED


def test_tcp_drop_without_announcement_is_fast_stop(start_server, open_wire) -> None:
    server = start_server("tcp://127.0.0.1:0")
    a, observer = open_wire(server.url), open_wire(server.url)
    assert a.request(Cmd.LOOP).ok
    a.close()
    deadline = time.monotonic() + 3.0
    while not observer.request(Cmd.GET_SYSTEM_STATE).fields["state"] & SystemFlags.SF_FAST_STOP:
        assert time.monotonic() < deadline, "no FAST STOP after an unannounced drop"
    assert observer.request(Cmd.HOMING).status == S.E_ACCESS_DENIED
    assert observer.request(Cmd.ACK_FAST_STOP, key=b"ack").ok
    assert observer.run(Cmd.HOMING).ok


def test_tcp_announced_disconnect(start_server, open_wire) -> None:
    server = start_server("tcp://127.0.0.1:0")
    a, observer = open_wire(server.url), open_wire(server.url)
    assert a.request(Cmd.DISCONNECT).ok
    assert a.request(Cmd.GET_WIDTH).status == S.E_ACCESS_DENIED
    a.close()
    time.sleep(0.1)
    assert not observer.request(Cmd.GET_SYSTEM_STATE).fields["state"] & SystemFlags.SF_FAST_STOP
    # a new connection starts afresh
    assert open_wire(server.url).request(Cmd.GET_WIDTH).ok


def test_tcp_request_close_fault(start_server, open_wire) -> None:
    server = start_server("tcp://127.0.0.1:0")
    a = open_wire(server.url)
    assert a.request(Cmd.LOOP).ok
    server.faults.request_close()
    with pytest.raises(ConnectionError):
        a.packets(timeout=2.0)
    # documented choice: a server-side drop is an unannounced end of the link -> FAST STOP
    b = open_wire(server.url)
    assert b.request(Cmd.GET_SYSTEM_STATE).fields["state"] & SystemFlags.SF_FAST_STOP


def test_tcp_split_byte_by_byte_and_noise(start_server, open_wire) -> None:
    server = start_server("tcp://127.0.0.1:0")
    wire = open_wire(server.url)
    packet = encode_packet(Cmd.LOOP, encode_request(Cmd.LOOP, data=b"\xaa\xaa\xaa"))
    for byte in b"\x00\xaa\x17" + packet:
        wire.send_raw(bytes([byte]))
    assert wire.expect(Cmd.LOOP).fields["data"] == b"\xaa\xaa\xaa"


def test_bad_checksum_answered_with_checksum_error(start_server, open_wire) -> None:
    server = start_server("tcp://127.0.0.1:0")
    wire = open_wire(server.url)
    bad = bytearray(encode_packet(Cmd.GET_WIDTH, encode_request(Cmd.GET_WIDTH)))
    bad[-1] ^= 0x55
    wire.send_raw(bytes(bad))
    reply = wire.expect(Cmd.GET_WIDTH)
    assert reply.status == S.E_CHECKSUM_ERROR


def test_checksum_evaluation_off_accepts_any_checksum(start_server, open_wire) -> None:
    server = start_server("tcp://127.0.0.1:0", verify_checksum=False)
    wire = open_wire(server.url)
    payload = encode_request(Cmd.GET_WIDTH)
    header = b"\xaa\xaa\xaa" + bytes([Cmd.GET_WIDTH, len(payload), 0])
    wire.send_raw(header + payload + b"\x00\x00")
    assert wire.expect(Cmd.GET_WIDTH).ok


def test_half_packet_dropped_after_silent_gap(start_server, open_wire) -> None:
    server = start_server("tcp://127.0.0.1:0")
    wire = open_wire(server.url)
    packet = encode_packet(Cmd.LOOP, b"12345")
    wire.send_raw(packet[:6] + b"\xff")  # header claims 5 bytes; only one arrives
    time.sleep(0.15)  # silent gap: the simulator drops the half packet
    wire.send_raw(encode_packet(Cmd.GET_WIDTH, encode_request(Cmd.GET_WIDTH)))
    assert wire.expect(Cmd.GET_WIDTH).ok


def test_pty_half_packet_dropped_after_silent_gap(start_server, open_wire) -> None:
    server = start_server("pty")
    wire = open_wire(server.url)
    wire.send_raw(encode_packet(Cmd.LOOP, b"123456789")[:9])
    time.sleep(0.15)
    assert wire.request(Cmd.LOOP, data=b"ok").fields["data"] == b"ok"
    assert wire.request(Cmd.DISCONNECT).status == S.E_NOT_AVAILABLE  # not a connection-oriented link


# --------------------------------------------------------------------------------------------------- UDP


def test_udp_replies_to_each_sender(start_server, open_wire) -> None:
    server = start_server("udp://127.0.0.1:0")
    assert "?local_port=0" in server.url
    a, b = open_wire(server.url), open_wire(server.url)
    assert a.run(Cmd.HOMING).ok
    assert b.request(Cmd.GET_WIDTH).fields["width"] == pytest.approx(110.0)
    assert b.request(Cmd.DISCONNECT).status == S.E_NOT_AVAILABLE
    assert a.packets(timeout=0.2) == []  # b's replies never went to a


# ------------------------------------------------------------------------------------------------- faults


def test_faults_drop_corrupt_truncate_garbage_delay_silent(start_server, open_wire) -> None:
    server = start_server("tcp://127.0.0.1:0")
    wire = open_wire(server.url)
    faults = server.faults

    faults.drop_replies()
    wire.send(Cmd.LOOP, data=b"1")
    assert wire.packets(timeout=0.3) == []
    assert wire.request(Cmd.LOOP, data=b"2").fields["data"] == b"2"

    faults.corrupt_replies()
    wire.send(Cmd.LOOP, data=b"3")
    deadline = time.monotonic() + 2.0
    while not any(isinstance(e, ChecksumError) for e in wire.events):
        assert time.monotonic() < deadline
        wire.packets(timeout=0.1)

    faults.truncate_replies()
    wire.send(Cmd.LOOP, data=b"4")
    assert wire.packets(timeout=0.3) == []
    wire.parser.reset()
    wire.parser.feed(b"")

    faults.send_garbage(b"\xaa\x00\xaa\xaa")
    assert wire.request(Cmd.LOOP, data=b"5").fields["data"] == b"5"

    faults.delay_replies(0.3)
    wire.send(Cmd.LOOP, data=b"6")
    assert wire.request(Cmd.GET_WIDTH).ok  # overtakes the delayed reply
    assert wire.expect(Cmd.LOOP).fields["data"] == b"6"

    faults.silent = True
    wire.send(Cmd.LOOP, data=b"7")
    assert wire.packets(timeout=0.3) == []
    faults.silent = False
    assert wire.request(Cmd.LOOP, data=b"8").fields["data"] == b"8"


# ----------------------------------------------------------------------------------------- auto updates


def test_auto_updates_flow_over_tcp(start_server, open_wire) -> None:
    server = start_server("tcp://127.0.0.1:0", time_scale=20.0)
    wire = open_wire(server.url)
    assert wire.request(Cmd.GET_SYSTEM_STATE, auto_update=True, period_ms=100).ok
    updates = [wire.expect(Cmd.GET_SYSTEM_STATE) for _ in range(3)]
    assert all(u.ok for u in updates)
    assert wire.run(Cmd.HOMING).ok  # async replies interleave with the updates
    wire.send(Cmd.GET_SYSTEM_STATE)  # auto update off (its reply is one more 40h packet)
    time.sleep(0.1)
    while wire.packets(timeout=0.05):
        pass
    assert [p for p in wire.packets(timeout=0.2) if p.command == Cmd.GET_SYSTEM_STATE] == []


def test_part_helpers_and_model_access(start_server, open_wire) -> None:
    server = start_server("tcp://127.0.0.1:0", part_width_mm=30.0)
    wire = open_wire(server.url)
    assert wire.run(Cmd.HOMING).ok
    assert wire.run(Cmd.GRIP, width=30.0, speed=200.0).ok
    server.remove_part()
    assert wire.request(Cmd.GET_GRASPING_STATE).fields["state"] == GraspingState.PART_LOST
    with server.lock:
        assert server.model.stats_lost == 1


# ------------------------------------------------------------------------------------------- life cycle


def test_close_releases_everything_and_is_idempotent() -> None:
    before = set(os.listdir("/proc/self/fd"))
    servers = [
        serve(WsgModel(), url, time_scale=50.0) for url in ("tcp://127.0.0.1:0", "udp://127.0.0.1:0", "pty")
    ]
    with serve(WsgModel(), "tcp://127.0.0.1:0") as tcp:
        sock = socket.create_connection(tcp.url.removeprefix("wsg+tcp://").rsplit(":", 1))
        sock.sendall(encode_packet(Cmd.LOOP))
        sock.recv(100)
    sock.close()
    for server in servers:
        server.close()
        server.close()
        assert server.closed and not server._thread.is_alive()
    assert not tcp._thread.is_alive()
    assert set(os.listdir("/proc/self/fd")) <= before


def test_listen_url_errors() -> None:
    with pytest.raises(ValueError):
        serve(WsgModel(), "http://127.0.0.1:0")
    with pytest.raises(ValueError):
        serve(WsgModel(), "can://virtual/x?foo=1")
    with pytest.raises(ValueError):
        serve(WsgModel(), "can:///x")


def test_server_packet_type_roundtrip_helper() -> None:
    # the family URL of a TCP server names the bound port
    with serve(WsgModel(), "tcp://127.0.0.1:0") as server:
        port = int(server.url.rsplit(":", 1)[1])
        assert port > 0 and server.url == f"wsg+tcp://127.0.0.1:{port}"
        assert isinstance(server.clock.now(), float)
    assert Packet(1, b"").command == 1
