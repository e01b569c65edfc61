"""The simulators under malformed input: they answer what the real device would and keep serving.

Real transports throughout (loopback TCP, a virtual CAN bus, a pty). Property tests here are bounded to a few
dozen examples in every mode: each example is a network round trip, and the decoders they exercise are
fuzzed at full rate in test_fuzz_*.py.
"""

from __future__ import annotations

import math
import os
import select
import socket
import struct
import time

import can
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from grippers.drivers.stepfoc.can_client import StepfocBus
from grippers.drivers.stepfoc.can_protocol import Cmd, decode_status, pack_id
from grippers.drivers.stepfoc.sim import MsgModel
from grippers.drivers.wsg.commands import COMMANDS, RequestFormatError, decode_request
from grippers.drivers.wsg.protocol import Packet, PacketParser, Status, encode_packet
from grippers.drivers.wsg.sim import WsgModel, serve

NETWORK = settings(max_examples=40, deadline=None)


@pytest.fixture(scope="module")
def wsg_server():
    with serve(WsgModel(), "tcp://127.0.0.1:0", time_scale=50) as server:
        yield server
        assert server.error is None


def _exchange(server, data: bytes, until: bytes, timeout: float = 3.0) -> list[Packet]:
    """Send ``data`` on a fresh connection; the packets received until a LOOP echo of ``until``."""
    host, port = server.address
    out: list[Packet] = []
    parser = PacketParser()
    with socket.create_connection((host, port), timeout=timeout) as sock:
        sock.sendall(data + encode_packet(0x06, until))
        deadline = time.monotonic() + timeout
        while time.monotonic() < deadline:
            sock.settimeout(max(0.01, deadline - time.monotonic()))
            chunk = sock.recv(4096)
            assert chunk, "the simulator closed the connection"
            for item in parser.feed(chunk):
                assert isinstance(item, Packet), f"the simulator sent a bad packet: {item!r}"
                out.append(item)
                if item.command == 0x06 and item.payload == b"\x00\x00" + until:
                    sock.sendall(encode_packet(0x07))  # announce the disconnect: no FAST STOP
                    return out
    raise AssertionError(f"no LOOP echo within {timeout} s; got {out}")


malformed = st.one_of(
    st.tuples(st.sampled_from(sorted(COMMANDS)), st.binary(max_size=40)),
    st.tuples(st.integers(0, 0xFF).filter(lambda c: c not in COMMANDS and c != 0xAA), st.binary(max_size=8)),
).filter(lambda r: _refusal(*r) is not None)


def _refusal(cmd: int, payload: bytes) -> int | None:
    try:
        decode_request(cmd, payload)
    except RequestFormatError as exc:
        return int(exc.status)
    return None


@NETWORK
@given(request=malformed)
def test_wsg_sim_answers_malformed_requests_like_the_device(wsg_server, request) -> None:
    """Wrong lengths: E_CMD_FORMAT_ERROR / E_NO_PARAM_EXPECTED; unknown ids: E_CMD_UNKNOWN (manual App. A)."""
    cmd, payload = request
    replies = _exchange(wsg_server, encode_packet(cmd, payload), b"still here")
    assert [(p.command, p.status) for p in replies[:-1]] == [(cmd, _refusal(cmd, payload))]


@NETWORK
@given(garbage=st.binary(max_size=200))
def test_wsg_sim_survives_garbage_and_answers_the_next_packet(wsg_server, garbage: bytes) -> None:
    """Noise is skipped; a false header is dropped after the silent gap; a checksum failure is answered with
    E_CHECKSUM_ERROR under the packet's id (WSG manual 4.0.x §1.2.1)."""
    replies = _exchange(wsg_server, garbage, b"after garbage")
    for p in replies[:-1]:
        assert p.status in {s.value for s in Status}


def test_wsg_sim_answers_a_corrupt_checksum_with_e_checksum_error(wsg_server) -> None:
    bad = bytearray(encode_packet(0x43, b"\x00\x00\x00"))
    bad[-1] ^= 0xFF
    replies = _exchange(wsg_server, bytes(bad), b"x")
    assert [(p.command, p.status) for p in replies[:-1]] == [(0x43, Status.E_CHECKSUM_ERROR)]


# ----------------------------------------------------------------------------------------------- MSG CAN


@pytest.fixture
def can_node(msg_can_sim, can_channel):
    server = msg_can_sim(MsgModel(node=2))
    raw = can.Bus(interface="virtual", channel=can_channel)
    yield server, raw
    raw.shutdown()


def _frames(raw: can.BusABC, wait: float = 0.1) -> list[can.Message]:
    out = []
    while (msg := raw.recv(timeout=wait)) is not None:
        out.append(msg)
    return out


@pytest.mark.parametrize("length", range(9))
def test_msg_sim_answers_a_61_of_any_length_with_a_60(can_node, length: int) -> None:
    """docs/protocols.md §2: every 61 frame, whatever its length, is answered by a status frame."""
    server, raw = can_node
    ident = pack_id(2, Cmd.GRIPPER_COMMAND)
    raw.send(can.Message(arbitration_id=ident, data=bytes(length), is_extended_id=False))
    (reply,) = _frames(raw)
    assert reply.arbitration_id == pack_id(2, Cmd.GRIPPER_STATUS)
    decode_status(bytes(reply.data))
    if length != 5:
        assert server.model.activated is False  # only a 5-byte frame is a command


def test_msg_sim_and_client_survive_random_frames_on_the_bus(msg_can_sim, can_channel) -> None:
    """Random frames (any id, length, remote or extended; reset/set-id/e-stop/watchdog to the node excluded,
    since a real node obeys those) on the bus: neither the simulator nor the client's reader dies; polls are
    answered. (Found: a standard frame with an id above 0x7FF killed the client's reader thread.)"""
    import random

    rnd = random.Random(7)
    server = msg_can_sim(MsgModel(node=1))
    raw = can.Bus(interface="virtual", channel=can_channel)
    with StepfocBus(interface="virtual", channel=can_channel) as bus:
        node = bus.node(1, timeout=0.5)
        for _ in range(2000):
            ident = rnd.randrange(0x800)
            obeyed = (Cmd.SET_CAN_ID, Cmd.RESET, Cmd.ESTOP, Cmd.WATCHDOG)
            if (ident >> 7) == 1 and (ident >> 1) & 0x3F in obeyed:
                continue
            extended = rnd.random() < 0.1
            if not extended and rnd.random() < 0.05:  # an "11-bit" id above 0x7FF: virtual buses carry it
                ident = rnd.randrange(0x800, 1 << 29)
            raw.send(
                can.Message(
                    arbitration_id=ident | (rnd.randrange(1 << 18) << 11 if extended else 0),
                    data=bytes(rnd.randrange(256) for _ in range(rnd.randrange(9))),
                    is_remote_frame=rnd.random() < 0.2,
                    is_extended_id=extended,
                )
            )
        assert node.poll() is not None
        assert node.device_info().serial == server.model.serial
        assert bus.alive
    raw.shutdown()
    assert server.error is None


# ---------------------------------------------------------------------------------------------- MSG UART


@pytest.fixture(scope="module")
def uart_port():
    from grippers.drivers.stepfoc.sim import serve_uart

    server = serve_uart(MsgModel(), "pty", time_scale=200)
    fd = os.open(server.path, os.O_RDWR | os.O_NOCTTY)
    import tty

    tty.setraw(fd)
    yield server, fd
    os.close(fd)
    server.close()


def _read_until(fd: int, marker: bytes, timeout: float = 3.0) -> bytes:
    data = b""
    deadline = time.monotonic() + timeout
    while marker not in data:
        left = deadline - time.monotonic()
        assert left > 0, f"no {marker!r} within {timeout} s; got {data[-200:]!r}"
        ready, _, _ = select.select([fd], [], [], left)
        if ready:
            data += os.read(fd, 4096)
    return data


@NETWORK
@given(garbage=st.binary(max_size=300))
def test_uart_sim_survives_garbage_and_answers_the_next_command(uart_port, garbage: bytes) -> None:
    """The firmware's receiver: '#' restarts a line, over-long lines are dropped, unknown names get
    'Unknown command' (docs/protocols.md §2 UART); the next command is answered."""
    server, fd = uart_port
    garbage = garbage.replace(b"#", b"")  # a garbage command could legitimately change the gripper
    os.write(fd, garbage + b"#Gripper\n")
    reply = _read_until(fd, b"Gripper: 1\r\n")
    assert reply.endswith(b"Gripper: 1\r\n")


# ------------------------------------------------------------------------- the pure models, at full rate

_SPECIAL = [math.nan, math.inf, -math.inf, 0.0, -0.0, 1e38, -1e38, 1e-38, -1.0, 5.0, 110.0, 1000.0]


@st.composite
def _wsg_request(draw: st.DrawFn) -> Packet:
    """A well-framed request of the right length whose floats are odd (NaN, inf, huge, negative)."""
    cmd = draw(st.sampled_from(sorted(COMMANDS)))
    layout = COMMANDS[cmd].request
    payload = bytearray(draw(st.binary(min_size=layout.size, max_size=layout.size)))
    offset = 0
    for f in layout.fixed:
        if f.fmt == "f" and draw(st.booleans()):
            struct.pack_into("<f", payload, offset, draw(st.sampled_from(_SPECIAL)))
        offset += struct.calcsize("<" + f.fmt)
    if layout.tail is not None:
        payload += draw(st.binary(max_size=80))
    return Packet(cmd, bytes(payload))


@given(
    requests=st.lists(st.tuples(_wsg_request(), st.sampled_from([0.0, 0.01, 0.5, 5.0])), max_size=8),
    part=st.none() | st.just(30.0),
)
def test_fuzz_wsg_model_answers_every_well_framed_request(requests, part, fuzz_count) -> None:
    """Any value in a request of the right length: the model answers with a known status, never raises."""
    fuzz_count["wsg simulator model: odd values"] += 1
    model = WsgModel(part_width_mm=part)
    now = 0.0
    for packet, dt in requests:
        for raw in model.handle(packet, now) + model.advance(now + dt):
            (reply,) = PacketParser().feed(raw)
            assert isinstance(reply, Packet) and reply.status in {s.value for s in Status}
        now += dt


@given(
    frames=st.lists(
        st.tuples(
            st.integers(0, 15),
            st.integers(0, 63),
            st.binary(max_size=8),
            st.booleans(),
            st.sampled_from([0.0, 0.01, 0.5, 5.0]),
        ),
        max_size=10,
    )
)
def test_fuzz_msg_model_survives_any_frame(frames, fuzz_count) -> None:
    fuzz_count["msg simulator model: any frame"] += 1
    model = MsgModel(node=3)
    now = 0.0
    for node, command, data, remote, dt in frames:
        for reply in model.handle_frame(pack_id(node, command), data, remote, now):
            assert 0 <= reply.arbitration_id <= 0x7FF and len(reply.data) <= 8
        now += dt
        model.advance(now)
        model.due_frames(now)
        assert 0 <= model.status(now).position <= 255
