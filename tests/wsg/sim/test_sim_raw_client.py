"""A client written from the WSG manual alone (4.0.x §1.2, §3, Appendix A/B/D) drives the simulator over TCP.

Deliberately imports nothing from ``drivers``: packets, the checksum and the reply layouts are built here
from the manual's text, so a mistake shared by our codec and our simulator cannot hide. The simulator is
started by a fixture (``raw_tcp_address``: a WSG 50 with a 40 mm part between its fingers) and, as the issue
asks, by the command line (``grippers sim wsg``) in a subprocess.
"""

from __future__ import annotations

import importlib.util
import re
import selectors
import socket
import struct
import subprocess
import sys

import pytest

# Appendix D: a 256-entry table (the MSB-first table of the polynomial 0x1021: entry 1 is 0x1021) and the
# update crc = TABLE[(crc ^ byte) & 0xFF] ^ (crc >> 8), starting at 0xFFFF, over the packet from the preamble.
TABLE = []
for _i in range(256):
    _c = _i << 8
    for _ in range(8):
        _c = ((_c << 1) ^ 0x1021) if _c & 0x8000 else _c << 1
    TABLE.append(_c & 0xFFFF)


def checksum(data: bytes) -> int:
    crc = 0xFFFF
    for byte in data:
        crc = TABLE[(crc ^ byte) & 0xFF] ^ (crc >> 8)
    return crc


def packet(command: int, payload: bytes = b"") -> bytes:
    """§1.2.1: AAh AAh AAh, id, size (little endian), payload, checksum (low byte first)."""
    body = b"\xaa\xaa\xaa" + bytes([command]) + struct.pack("<H", len(payload)) + payload
    return body + struct.pack("<H", checksum(body))


# Appendix A status codes used here
E_SUCCESS, E_NOT_INITIALIZED, E_NO_PARAM_EXPECTED, E_CMD_UNKNOWN = 0, 3, 12, 14
E_ACCESS_DENIED, E_CMD_PENDING = 16, 26
SF_REFERENCED, SF_MOVING = 1 << 0, 1 << 1  # Appendix B
IDLE, HOLDING = 0, 4  # §3.4.2


class RawClient:
    def __init__(self, address: tuple[str, int]) -> None:
        self.sock = socket.create_connection(address, timeout=5.0)

    def _read(self, n: int) -> bytes:
        data = b""
        while len(data) < n:
            chunk = self.sock.recv(n - len(data))
            assert chunk, "connection closed"
            data += chunk
        return data

    def receive(self) -> tuple[int, int, bytes]:
        """One reply: (command id, status code, data after the status)."""
        head = self._read(6)
        assert head[:3] == b"\xaa\xaa\xaa", head
        size = struct.unpack("<H", head[4:6])[0]
        rest = self._read(size + 2)
        # §1.2.2: the checksum over the whole packet including the checksum field gives 0
        assert checksum(head + rest) == 0
        status = struct.unpack("<H", rest[0:2])[0]
        return head[3], status, rest[2:size]

    def ask(self, command: int, payload: bytes = b"") -> tuple[int, bytes]:
        self.sock.sendall(packet(command, payload))
        cmd, status, data = self.receive()
        assert cmd == command
        return status, data

    def run(self, command: int, payload: bytes = b"") -> int:
        """§1.3: an asynchronous command answers E_CMD_PENDING, then its result under the same id."""
        status, _ = self.ask(command, payload)
        assert status == E_CMD_PENDING
        cmd, status, _ = self.receive()
        assert cmd == command
        return status

    def state(self) -> int:
        status, data = self.ask(0x40, b"\x00\x00\x00")  # §3.4.1, auto update off
        assert status == E_SUCCESS
        return struct.unpack("<I", data)[0]


def test_manual_examples_check_out() -> None:
    # §1.2.1 examples 1 and 2, §1.2.2 example 1
    assert packet(0x01) == bytes.fromhex("AAAAAA010000E810")
    assert packet(0x01, b"\x12\x34") == bytes.fromhex("AAAAAA01020012346D66")
    assert checksum(bytes.fromhex("AAAAAA2002000000B3FD")) == 0


def test_raw_client_homes_moves_grips_releases(raw_tcp_address) -> None:
    _session(raw_tcp_address)


@pytest.mark.skipif(importlib.util.find_spec("grippers.backends.wsg_cli") is None, reason="CLI not landed")
def test_raw_client_against_the_command_line_simulator() -> None:
    cmd = [
        sys.executable,
        "-m",
        "grippers",
        "sim",
        "wsg",
        "--listen",
        "tcp://127.0.0.1:0",
        "--time-scale",
        "50",
        "--part-width",
        "40",
    ]
    proc = subprocess.Popen(cmd, stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True)
    try:
        selector = selectors.DefaultSelector()
        selector.register(proc.stdout, selectors.EVENT_READ)
        printed = ""
        while not re.search(r"127\.0\.0\.1:\d+", printed):
            assert selector.select(timeout=15.0), f"simulator printed no address: {printed!r}"
            line = proc.stdout.readline()
            assert line, f"simulator exited: {printed!r}"
            printed += line
        port = int(re.search(r"127\.0\.0\.1:(\d+)", printed).group(1))
        _session(("127.0.0.1", port))
    finally:
        proc.terminate()
        try:
            proc.wait(timeout=5.0)
        except subprocess.TimeoutExpired:
            proc.kill()
            proc.wait()
        proc.stdout.close()


def _session(address: tuple[str, int]) -> None:
    c = RawClient(address)
    try:
        status, info = c.ask(0x50)  # §3.5.1 system information
        assert status == E_SUCCESS and len(info) == 8
        assert info[0] == 1  # WSG 50
        assert info[2:4] == struct.pack("<H", 0x4010)  # firmware 4.0.1 as nibbles

        status, limits = c.ask(0x53)  # §3.5.4
        stroke, min_speed, max_speed = struct.unpack("<3f", limits[:12])
        assert status == E_SUCCESS and stroke == pytest.approx(110.0) and min_speed < max_speed

        assert not c.state() & SF_REFERENCED
        # §3.2.2: motion before homing -> E_NOT_INITIALIZED
        status, _ = c.ask(0x21, b"\x00" + struct.pack("<ff", 50.0, 100.0))
        assert status == E_NOT_INITIALIZED

        assert c.run(0x20, b"\x00") == E_SUCCESS  # §3.2.1 homing, default direction
        assert c.state() & SF_REFERENCED

        assert c.run(0x21, b"\x02" + struct.pack("<ff", 60.0, 200.0)) == E_SUCCESS  # absolute, stop on block
        status, data = c.ask(0x43, b"\x00\x00\x00")  # §3.4.4 width
        assert status == E_SUCCESS and struct.unpack("<f", data)[0] == pytest.approx(60.0, abs=0.01)
        assert not c.state() & SF_MOVING

        status, _ = c.ask(0x32, struct.pack("<f", 20.0))  # §3.3.3 force limit
        assert status == E_SUCCESS
        assert c.run(0x25, struct.pack("<ff", 40.0, 100.0)) == E_SUCCESS  # §3.2.6 grip the 40 mm part
        status, data = c.ask(0x41, b"\x00\x00\x00")  # §3.4.2
        assert status == E_SUCCESS and data[0] == HOLDING
        status, data = c.ask(0x45, b"\x00\x00\x00")  # §3.4.6 force
        assert status == E_SUCCESS and struct.unpack("<f", data)[0] == pytest.approx(20.0)

        assert c.run(0x26, struct.pack("<ff", 80.0, 100.0)) == E_SUCCESS  # §3.2.7 release
        status, data = c.ask(0x41, b"\x00\x00\x00")
        assert data[0] == IDLE
        status, data = c.ask(0x42, b"\x00")  # §3.4.3 statistics (id 42h)
        assert status == E_SUCCESS and struct.unpack("<IHH", data) == (1, 0, 0)

        assert c.ask(0x90)[0] == E_CMD_UNKNOWN  # §1.2.2 example 2
        assert c.ask(0x22, b"\x01")[0] == E_NO_PARAM_EXPECTED  # §3.2.3

        assert c.ask(0x07)[0] == E_SUCCESS  # §3.1.2 disconnect announcement
        assert c.ask(0x43, b"\x00\x00\x00")[0] == E_ACCESS_DENIED
    finally:
        c.sock.close()
