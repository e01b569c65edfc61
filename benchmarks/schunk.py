"""Target 18: a SCHUNK state poll's CPU against the wire (issue 41 §5).

* Web API on loopback: the simulator serves in a child process (its own interpreter, so it does not share
  our GIL). The figure is this thread's CPU time per ``Gripper.state()`` of the SCHUNK backend (one ``GET
  /adi/data.json?inst=0x0040&count=1`` and its decoding into an SI state); the baseline, measured in the
  same run, is the CPU of the bare request any client must make: the same GET on a kept-alive
  ``http.client`` connection, its JSON read. Goal: the library adds at most half again (ratio <= 1.5). The
  poll rate reached (wall) is reported against SCHUNK's driver's 50 ms cycle.
* Modbus RTU at 115200 baud 8E1: the CPU of one ``state()`` over an in-memory link that answers at once
  (framing, CRC, decoding), against the wire time of that poll (FC 03 of 8 registers: 8 B request, 21 B
  reply, 11 bits per character with the parity bit, plus two t3.5 silences). Goal: at most 10 %.
"""

from __future__ import annotations

import argparse
import http.client
import sys
import time
from pathlib import Path
from typing import Any

if __package__ in (None, ""):
    sys.path.insert(0, str(Path(__file__).resolve().parent.parent))

from benchmarks.common import Result, SimChild, serve_as_child
from grippers.drivers import modbus
from grippers.drivers.links import ByteLink
from grippers.drivers.schunk.protocol import PLC_INPUT, ProcessInput, Status

BAUD = 115200
BITS_PER_CHAR = 11  # 8E1: start, 8 data, parity, stop
HTTP_RATIO_TARGET = 1.5
RTU_FRACTION_TARGET = 0.10
SCHUNK_POLL_HZ = 20.0  # SCHUNK's driver: update_cycle 0.05 s


def _best(polls: int, call) -> tuple[float, float]:  # noqa: ANN001 - a zero-argument callable
    """(CPU, wall) seconds of one call, each the best of three runs of ``polls`` calls."""
    cpu = wall = float("inf")
    for _ in range(3):
        t0, w0 = time.thread_time(), time.perf_counter()
        for _ in range(polls):
            call()
        cpu = min(cpu, (time.thread_time() - t0) / polls)
        wall = min(wall, (time.perf_counter() - w0) / polls)
    return cpu, wall


def servo_rate(g: Any, seconds: float) -> float:
    """Servo targets per second the device's servo feature puts on the wire (each: the empty word and a
    move word, two POSTs), new targets back to back."""
    from grippers.servo import ServoTarget

    g.home()
    servo = g.device.servo
    servo.begin()
    n, t0 = 0, time.perf_counter()
    while time.perf_counter() - t0 < seconds:
        n += 1
        servo.send(ServoTarget(0.04 + (n % 50) / 1e4, 0.05, None))
    servo.end()
    return n / (time.perf_counter() - t0)


def http_poll(polls: int) -> tuple[float, float, float, float]:
    """(our CPU per state(), the bare GET's CPU, our wall time per state(), servo targets per second)
    against the child simulator."""
    import grippers
    from grippers.urls import parse_url

    child = SimChild("schunk.py", "--serve-http", "schunk+http://")
    try:
        where = parse_url(child.where)  # the one URL grammar
        bare = http.client.HTTPConnection(where.host or "127.0.0.1", where.port or 80, timeout=1.0)

        def get() -> None:
            bare.request("GET", "/adi/data.json?inst=0x0040&count=1")
            bare.getresponse().read()

        base_cpu, _ = _best(polls, get)
        bare.close()
        with grippers.open(child.where) as g:
            cpu, wall = _best(polls, g.state)
            rate = servo_rate(g, 0.5 if polls < 1000 else 2.0)
        return cpu, base_cpu, wall, rate
    finally:
        child.close()


class _AnsweringLink(ByteLink):
    """Answers every FC 03 at once with a moving unit's process data (no I/O, no thread)."""

    def __init__(self) -> None:
        super().__init__("bench")
        self._reply, self._n = b"", 0

    def _send(self, data: bytes) -> None:
        self._n += 1
        count = int.from_bytes(data[4:6], "big")
        address = int.from_bytes(data[2:4], "big")
        if address + 1 == PLC_INPUT:
            from grippers.drivers.schunk.protocol import Fieldbus

            payload = ProcessInput(Status.READY | Status.RECEIVED, 40_000 + self._n % 1000, 0, 0, 0).encode(
                Fieldbus.MODBUS
            )
        else:
            payload = self._parameter(address + 1)
        regs = [int.from_bytes(payload[i : i + 2], "big") for i in range(0, 2 * count, 2)]
        self._reply = modbus.read_response(data[0], data[1], regs)

    @staticmethod
    def _parameter(inst: int) -> bytes:
        from grippers.drivers.schunk.protocol import Fieldbus, encode, parameter

        values = {0x1130: 7, 0x0500: 11, 0x1000: "BENCH", 0x1118: "1.0", 0x1020: 1, 0x1110: 1}
        p = parameter(inst)
        return encode(inst, values.get(inst, 50.0 if p.kind.value == "float" else 0), Fieldbus.MODBUS)

    def _recv(self, timeout: float) -> bytes:
        reply, self._reply = self._reply, b""
        return reply

    def _close(self) -> None:
        pass


def rtu_poll(polls: int) -> tuple[float, float]:
    """(CPU per state() over RTU, the wire time of that poll at 115200 8E1)."""
    from grippers.backends.schunk import SchunkDevice
    from grippers.backends.schunk_profile import SchunkProfile
    from grippers.drivers.schunk.client import SchunkClient
    from grippers.drivers.schunk.rtu import RtuLink
    from grippers.gripper import Gripper
    from grippers.profiles import load_profile

    profile = load_profile("schunk-egu-60")
    assert isinstance(profile, SchunkProfile)
    client = SchunkClient(RtuLink(_AnsweringLink(), slave=12))
    client.connect()
    url = "schunk+serial:///dev/bench"
    g = Gripper(SchunkDevice(client, profile, url, timeout=0.5), profile, url, timeout=0.5)
    try:
        cpu, _ = _best(polls, g.state)
    finally:
        g.close()
    request = len(modbus.read_request(12, PLC_INPUT - 1, 8))
    reply = len(modbus.read_response(12, modbus.READ_HOLDING, [0] * 8))
    wire = modbus.wire_seconds(request + reply, BAUD, BITS_PER_CHAR) + 2 * modbus.silent_interval(BAUD)
    return cpu, wire


def run(quick: bool) -> list[Result]:
    polls = 300 if quick else 2000
    cpu, base, wall, servo = http_poll(polls)
    ratio = cpu / base
    rtu_cpu, wire = rtu_poll(polls)
    fraction = rtu_cpu / wire
    return [
        Result(
            "18 schunk poll CPU, HTTP",
            f"{cpu * 1e6:.0f} us CPU",
            f"{base * 1e6:.0f} us bare GET",
            f"{ratio:.2f}x",
            f"<= {HTTP_RATIO_TARGET:.1f}x",
            ratio <= HTTP_RATIO_TARGET,
            [
                f"state() on loopback: {wall * 1e3:.2f} ms wall, {1 / wall:.0f} polls/s "
                f"({1 / wall / SCHUNK_POLL_HZ:.0f}x SCHUNK's driver's 20 Hz cycle); simulator in a child"
            ],
        ),
        Result(
            "18 schunk poll CPU/wire, RTU",
            f"{rtu_cpu * 1e6:.0f} us CPU",
            f"{wire * 1e3:.2f} ms wire",
            f"{fraction:.1%}",
            f"<= {RTU_FRACTION_TARGET:.0%}",
            fraction <= RTU_FRACTION_TARGET,
            ["FC 03 of 8 registers: 8 B + 21 B at 115200 baud 8E1 (11 bits per character) + 2 x t3.5"],
        ),
        Result(
            "18 schunk servo, HTTP",
            f"{servo:.0f} targets/s",
            f"{SCHUNK_POLL_HZ:.0f} Hz (SCHUNK's cycle)",
            f"{servo / SCHUNK_POLL_HZ:.1f}x",
            f">= {SCHUNK_POLL_HZ:.0f} Hz",
            servo >= SCHUNK_POLL_HZ,
            [
                "each target: the empty word and a move word (two POSTs); on RTU the two FC 16 writes of "
                f"8 registers take {2 * (_rtu_write_wire()) * 1e3:.1f} ms of wire, "
                f"{1 / (2 * _rtu_write_wire()):.0f} targets/s at most"
            ],
        ),
    ]


def _rtu_write_wire() -> float:
    request = len(modbus.write_request(12, PLC_INPUT + 7, [0] * 8))
    reply = len(modbus.write_response(12, PLC_INPUT + 7, 8))
    return modbus.wire_seconds(request + reply, BAUD, BITS_PER_CHAR) + 2 * modbus.silent_interval(BAUD)


def _serve_http() -> None:
    from grippers.backends import get_backend
    from grippers.profiles import load_profile
    from grippers.settings import Settings

    server = get_backend("schunk").simulator(load_profile("schunk-egu-60"), Settings("sim://bench", {}, {}))
    serve_as_child(server, server.url)


if __name__ == "__main__":
    ap = argparse.ArgumentParser()
    ap.add_argument("--serve-http", action="store_true")
    if ap.parse_args().serve_http:
        _serve_http()
    else:
        from benchmarks.common import format_table

        print(format_table(run(quick=True)))
