"""The MSG UART simulator answers as the STEPFOC firmware does (issue 12 §1, issue 13 item 9), driven by raw
lines written to the pseudo-terminal (no client code)."""

from __future__ import annotations

import os
import select
import time
from collections.abc import Iterator

import pytest

from grippers.drivers.stepfoc.can_protocol import Cmd, Watchdog, WatchdogAction, encode_frame
from grippers.drivers.stepfoc.sim import MsgModel, serve_uart, uart_server
from grippers.drivers.stepfoc.sim.uart_server import UartSimServer

from ..rawmodel import SteppedClock

KEPT_REQUESTS = getattr(uart_server, "KEPT_REQUESTS", 256)


class RawPort:
    def __init__(self, server: UartSimServer) -> None:
        self.fd = os.open(server.path, os.O_RDWR | os.O_NOCTTY)
        self.buf = b""

    def ask(self, line: bytes, wait: float = 5.0, quiet: float = 0.0) -> list[str]:
        """Write ``line``; return the answer lines. ``quiet`` (s): collect until that long passes silent.
        ``wait`` only bounds a missing answer (a complete line ends it at once): generous, so a simulator
        starved of the CPU on a busy machine is not taken for a firmware that did not answer."""
        os.write(self.fd, line)
        deadline = time.monotonic() + wait
        last = time.monotonic()
        while time.monotonic() < deadline:
            ready, _, _ = select.select([self.fd], [], [], 0.02)
            if ready:
                self.buf += os.read(self.fd, 4096)
                last = time.monotonic()
            else:
                silent = time.monotonic() - last >= quiet
                complete = self.buf.endswith(b"\r\n")
                if (complete and (not quiet or silent)) or (quiet and not self.buf and silent):
                    break
        lines, self.buf = self.buf.decode("latin-1").split("\r\n")[:-1], b""
        return lines

    def close(self) -> None:
        os.close(self.fd)


@pytest.fixture
def port() -> Iterator[tuple[UartSimServer, RawPort]]:
    server = serve_uart(MsgModel(), "pty", time_scale=100.0)
    raw = RawPort(server)
    yield server, raw
    raw.close()
    server.close()


def test_names_the_parser_does_not_know_get_no_answer(port) -> None:
    _, raw = port
    assert raw.ask(b"#Nosuchthing\n", wait=0.3, quiet=0.25) == []  # not even "Unknown command"
    assert raw.ask(b"#Idle 5\n", wait=0.3, quiet=0.25) == []  # Idle is known bare only
    assert raw.ask(b"#SIN\n") == ["Unknown command"]  # known to the parser, not dispatched
    assert raw.ask(b"#Gripper\n") == ["Gripper: 1"]


@pytest.fixture
def stepped() -> Iterator[tuple[SteppedClock, RawPort]]:
    """The UART simulator on a clock that moves only when the test moves it (issue 33 §5): a calibration or
    a motion is still running when the test asks, however long the machine keeps the test from asking."""
    clock = SteppedClock()
    server = serve_uart(MsgModel(), "pty", clock=clock)
    raw = RawPort(server)
    yield clock, raw
    raw.close()
    server.close()


def _calibrate(clock: SteppedClock, raw: RawPort) -> None:
    """#Gripcal, then move the clock a simulated second at a time until #Mode says the driver is idle again
    (60 simulated s at most): the calibration has ended."""
    assert raw.ask(b"#Gripcal\n") == ["Gripper calibration! "]
    for _ in range(60):
        if raw.ask(b"#Mode\n") == ["Idle mode "]:
            return
        clock.t += 1.0
    raise AssertionError("the calibration did not end within 60 simulated s")


def test_mode_tells_calibration_and_gripper_mode(stepped) -> None:
    clock, raw = stepped
    assert raw.ask(b"#Mode\n") == ["Idle mode "]
    assert raw.ask(b"#Gripcal\n") == ["Gripper calibration! "]
    assert raw.ask(b"#Mode\n") == ["Gripper calib mode"]  # no simulated time passed: it runs
    clock.t += 1.0
    assert raw.ask(b"#Mode\n") == ["Gripper calib mode"]  # a calibration takes seconds
    for _ in range(60):
        clock.t += 1.0
        if raw.ask(b"#Mode\n") == ["Idle mode "]:
            break
    assert raw.ask(b"#Mode\n") == ["Idle mode "]
    assert raw.ask(b"#Grippos 100\n")[0].startswith("Gripper current position is: ")
    assert raw.ask(b"#Mode\n", wait=0.3, quiet=0.25) == []  # gripper mode (11) prints nothing


def test_recalibration_keeps_the_calibrated_bit(stepped) -> None:
    clock, raw = stepped
    _calibrate(clock, raw)
    raw.ask(b"#Grippos 100\n")
    clock.t += 5.0  # the move ends
    raw.ask(b"#Gripcal\n")
    info = raw.ask(b"#Gripinfo\n")  # no simulated time passed since: the calibration runs
    assert "Gripper calibrated is: 1" in info and raw.ask(b"#Mode\n") == ["Gripper calib mode"]


def test_clear_idles_the_driver(stepped) -> None:
    clock, raw = stepped
    _calibrate(clock, raw)
    raw.ask(b"#Gripvel 0\n")
    raw.ask(b"#Grippos 0\n")  # slow: ~40 simulated s
    clock.t += 0.5
    moving = raw.ask(b"#Grippos\n")
    clock.t += 0.5
    assert raw.ask(b"#Grippos\n") != moving  # still under way
    assert raw.ask(b"#Clear\n") == ["Clear errors"]
    stopped = raw.ask(b"#Grippos\n")
    clock.t += 20.0
    assert raw.ask(b"#Grippos\n") == stopped and raw.ask(b"#Mode\n") == ["Idle mode "]


def test_requests_are_not_kept_forever(port) -> None:
    server, raw = port
    for _ in range(KEPT_REQUESTS + 50):
        os.write(raw.fd, b"#Gripvel\n")
    deadline = time.monotonic() + 5
    while getattr(server, "request_count", len(server.requests)) < KEPT_REQUESTS + 50:
        assert time.monotonic() < deadline
        raw.ask(b"", wait=0.05, quiet=0.02)
    assert len(server.requests) == KEPT_REQUESTS and server.request_count == KEPT_REQUESTS + 50


def test_a_driver_error_forces_idle_and_error_prints_it(port) -> None:
    """Issue 19 §1: any driver error forces mode 0, so ``#Gripcal`` does not run: ``#Mode`` prints "Idle
    mode", ``#Gripinfo`` shows only the estop bit (0 for command 0's e-stop), ``#Error`` names the cause
    (STEPFOC firmware communication.cpp "Error")."""
    server, raw = port
    assert raw.ask(b"#Error\n", quiet=0.2) == ["No errors!"]
    with server.lock:
        server.model.emergency_stop(server.clock.now())  # command 0 from another host on CAN
    assert raw.ask(b"#Gripcal\n") == ["Gripper calibration! "]
    assert raw.ask(b"#Mode\n") == ["Idle mode "]
    info = raw.ask(b"#Gripinfo\n", quiet=0.2)
    assert "Gripper estop status: 0" in info and "Gripper calibrated is: 0" in info
    assert raw.ask(b"#Error\n", quiet=0.2) == ["In error state!", "Received ESTOP command"]
    raw.ask(b"#Clear\n")
    assert raw.ask(b"#Gripcal\n") == ["Gripper calibration! "]
    assert raw.ask(b"#Mode\n") == ["Gripper calib mode"]


def test_uart_lines_do_not_feed_the_can_watchdog() -> None:
    """Issue 19 §1: ``CAN_watchdog`` is fed only by CAN 61 frames, data packs and remote requests; UART
    traffic never feeds it, and Save (13) keeps the period over a power cycle (STEPFOC firmware
    communication_CAN.cpp, EEPROM.cpp). A node whose watchdog was set and saved over CAN and which is then
    driven over UART alone trips "timeout" one period after the last CAN frame although UART lines keep coming
    and are answered."""
    model = MsgModel(current_noise=False)
    model.advance(0.0)
    setup = (  # raw CAN frames from an earlier session: a 200 ms watchdog, saved, then a reset (power cycle)
        encode_frame(0, Cmd.WATCHDOG, Watchdog(200, WatchdogAction.IDLE)),
        encode_frame(0, Cmd.SAVE_CONFIG),
        encode_frame(0, Cmd.RESET),
    )
    for i, frame in enumerate(setup, 1):
        model.handle_frame(frame.arbitration_id, frame.data, frame.remote, i * 0.001)
    fed = len(setup) * 0.001  # the reset restarts the watchdog's timer: the last "feed"
    clock = SteppedClock(start=fed)
    server = serve_uart(model, "pty", clock=clock)
    raw = RawPort(server)
    try:
        errors = []
        for step in range(1, 7):  # a UART line every 50 ms for 300 ms, against the 200 ms watchdog
            clock.t = fed + 0.05 * step
            assert raw.ask(b"#Grippos\n")[0].startswith("Gripper current position is: ")
            errors.append(raw.ask(b"#Error\n", quiet=0.2))
        assert errors[:3] == [["No errors!"]] * 3  # 50, 100, 150 ms: within the period
        assert errors[3:] == [["In error state!", "Watchdog error"]] * 3  # 200 ms on: tripped
        # the error forces mode 0: a calibration asked over UART does not run
        assert raw.ask(b"#Gripcal\n") == ["Gripper calibration! "]
        assert raw.ask(b"#Mode\n") == ["Idle mode "]
    finally:
        raw.close()
        server.close()
