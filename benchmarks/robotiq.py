"""Target 14: a Robotiq status poll against the wire, and the servo rate over a pty (issue 29 §5).

* Wire time of one status poll at 115200 baud 8N1: the FC 03 request (8 bytes) and its reply (11 bytes) at
  10 bits per byte, plus the two silent intervals (t3.5 = 1.75 ms above 19200 baud, Modbus over serial line
  V1.02 §2.5.1.1) that end them; the device's own turnaround is not counted (unknown, and not ours).
* The library's CPU time per poll: ``Gripper.state()`` of the Robotiq backend over an in-memory link that
  answers at once (so only our code runs: framing, CRC, parsing, decoding, the SI state), as a fraction of
  that wire time. Goal: at most 10 %, so the library is never what limits a poll.
* Servo over a pty: the simulator in a child process (its own interpreter, so it does not share our GIL)
  serves the RTU line; one FC 16 write of a new rPR per exchange, through the client with its t3.5 pause,
  as ``Gripper.servo`` sends them. Reported: exchanges per second (goal: at least the SDK's 100 Hz) and the
  p50 / p99 latency of one exchange.
"""

from __future__ import annotations

import argparse
import sys
import time
from pathlib import Path

if __package__ in (None, ""):
    sys.path.insert(0, str(Path(__file__).resolve().parent.parent))

from benchmarks.common import Result, SimChild, serve_as_child
from grippers.drivers.links import ByteLink
from grippers.drivers.robotiq import modbus
from grippers.drivers.robotiq.client import RobotiqClient
from grippers.drivers.robotiq.registers import (
    BLOCK_REGISTERS,
    STATUS_ADDRESS,
    ActivationState,
    Command,
    ObjectDetection,
    Status,
)

BAUD = 115200
CPU_FRACTION_TARGET = 0.10
SERVO_RATE_TARGET = 100.0


def poll_wire_seconds(baudrate: int = BAUD) -> tuple[int, int, float]:
    """Request bytes, reply bytes and the wire time of one status poll (both frames and their silences)."""
    request = len(modbus.read_request(9, STATUS_ADDRESS, BLOCK_REGISTERS))
    reply = len(modbus.read_response(9, modbus.READ_HOLDING, [0] * BLOCK_REGISTERS))
    return (
        request,
        reply,
        modbus.wire_seconds(request + reply, baudrate) + 2 * modbus.silent_interval(baudrate),
    )


class _AnsweringLink(ByteLink):
    """A link that answers every status read at once with a moving gripper's status (no I/O, no thread): a
    transport of the backend kit filling its three methods."""

    def __init__(self) -> None:
        super().__init__("bench")
        self._reply = b""
        self._n = 0

    def _send(self, data: bytes) -> None:
        self._n += 1
        st = Status(
            True, True, ActivationState.COMPLETE, ObjectDetection.MOVING, 0, 0, 200, self._n % 230, 16
        )
        self._reply = modbus.read_response(data[0], data[1], list(st.registers()))

    def _recv(self, timeout: float) -> bytes:
        reply, self._reply = self._reply, b""
        return reply

    def _close(self) -> None:
        pass


def cpu_per_poll(polls: int) -> float:
    """CPU seconds of one ``state()`` (this thread's CPU clock; best of three runs)."""
    from grippers.backends.robotiq import RobotiqProfile, robotiq_gripper
    from grippers.profiles import load_profile

    profile = load_profile("robotiq-2f85")
    assert isinstance(profile, RobotiqProfile)
    client = RobotiqClient(_AnsweringLink(), device="bench", timeout=0.5)
    g = robotiq_gripper(client, profile, "robotiq+serial:///dev/bench", timeout=0.5)
    best = float("inf")
    try:
        for _ in range(3):
            t0 = time.thread_time()
            for _ in range(polls):
                g.state()
            best = min(best, (time.thread_time() - t0) / polls)
    finally:
        g.close()
    return best


def servo_exchanges(seconds: float) -> tuple[float, list[float]]:
    """Exchanges per second and the latency of each (s): FC 16 writes of a new rPR over the pty."""
    sim = SimChild("robotiq.py", "--serve-pty", "/dev/")
    client = RobotiqClient.serial(sim.where, timeout=0.5)
    try:
        client.write_command(Command(act=True))
        latencies: list[float] = []
        t_end = time.perf_counter() + seconds
        t0 = time.perf_counter()
        i = 0
        while time.perf_counter() < t_end:
            i += 1
            cmd = Command(act=True, gto=True, position=(i * 7) % 230, speed=255, force=100)
            s = time.perf_counter()
            client.write_command(cmd, command="servo")
            latencies.append(time.perf_counter() - s)
        elapsed = time.perf_counter() - t0
        return len(latencies) / elapsed, latencies
    finally:
        client.close()
        sim.close()


def _pct(values: list[float], q: float) -> float:
    ordered = sorted(values)
    return ordered[min(len(ordered) - 1, int(q * len(ordered)))]


def run(quick: bool) -> list[Result]:
    req, rep, wire = poll_wire_seconds()
    cpu = cpu_per_poll(500 if quick else 3000)
    fraction = cpu / wire
    rate, lat = servo_exchanges(1.0 if quick else 4.0)
    return [
        Result(
            "14 robotiq poll CPU/wire",
            f"{cpu * 1e6:.0f} us CPU",
            f"{wire * 1e3:.2f} ms wire",
            f"{fraction:.1%}",
            f"<= {CPU_FRACTION_TARGET:.0%}",
            fraction <= CPU_FRACTION_TARGET,
            [
                f"one poll: request {req} B + reply {rep} B = {req + rep} B at {BAUD} baud 8N1 "
                f"({modbus.wire_seconds(req + rep) * 1e3:.2f} ms) + 2 x t3.5 "
                f"({modbus.silent_interval() * 1e3:.2f} ms)"
            ],
        ),
        Result(
            "14 robotiq servo over pty",
            f"{rate:.0f} Hz",
            f"{SERVO_RATE_TARGET:.0f} Hz (SDK)",
            f"{rate / SERVO_RATE_TARGET:.2f}x",
            f">= {SERVO_RATE_TARGET:.0f} Hz",
            rate >= SERVO_RATE_TARGET,
            [
                f"latency per exchange p50 {_pct(lat, 0.5) * 1e3:.2f} ms, p99 {_pct(lat, 0.99) * 1e3:.2f} ms "
                f"({len(lat)} FC 16 writes, t3.5 kept before each; simulator in a child process)",
                "a pty has no baud rate: on a 115200 line one such exchange (15 B + 8 B + 2 x t3.5) takes "
                f"{(modbus.wire_seconds(23) + 2 * modbus.silent_interval()) * 1e3:.2f} ms of wire",
            ],
        ),
    ]


def _serve_pty() -> None:
    from grippers.drivers.robotiq.sim import RobotiqModel, serve

    model = RobotiqModel()
    model.act, model.sta = True, ActivationState.COMPLETE
    server = serve(model, "pty")
    serve_as_child(server, server.path)


if __name__ == "__main__":
    ap = argparse.ArgumentParser()
    ap.add_argument("--serve-pty", action="store_true")
    if ap.parse_args().serve_pty:
        _serve_pty()
    else:
        for r in run(quick=True):
            print(r.name, r.figure, r.baseline, r.ratio, r.target, r.verdict, *r.notes, sep="  ")
