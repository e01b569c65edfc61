"""Issue 23 §2, the deadman whole: the server stops what the device does for a vanished holder, within
its own --lease-timeout whatever lease the client announced; a client whose server died is told so."""

from __future__ import annotations

import signal
import subprocess
import sys
import textwrap
import threading
import time

import pytest

import grippers
from grippers import ConnectionLost

from .conftest import ROOT, ServeProcess, sim

pytestmark = pytest.mark.timeout(90)

LEASE = 1.0
MARGIN = 1.0  # the publisher's period, a state read and a stop on a busy machine; the motion is 20 s long

TIMED_OUT = textwrap.dedent(
    """
    import sys, time, grippers
    g = grippers.open(sys.argv[1])
    g.home()
    try:
        g.move(g.limits.min_width + 0.001, g.limits.min_speed, timeout=0.3)
    except grippers.GripperTimeout:
        print("timed out", flush=True)
    time.sleep(60)
    """
)

SILENT = str(ROOT / "benchmarks" / "moving_controller.py")  # shared with the lease benchmark


def _controller(args: list[str], expect: str) -> subprocess.Popen[str]:
    proc = subprocess.Popen([sys.executable, *args], cwd=ROOT, stdout=subprocess.PIPE, text=True)
    assert proc.stdout is not None
    line = proc.stdout.readline().strip()
    if line != expect:
        proc.kill()
        proc.wait(5)
        pytest.fail(f"controller printed {line!r}, not {expect!r}")
    return proc


def _stopped_within(watcher: grippers.Gripper, since: float, bound: float) -> float:
    while watcher.state().moving:
        assert time.monotonic() - since < bound, "the motion is still running"
        time.sleep(0.01)
    width = watcher.state().width
    assert width > watcher.limits.min_width + 0.03  # stopped far from the target (20 s of travel)
    time.sleep(0.2)
    assert watcher.state().width == pytest.approx(width, abs=1e-4)
    return time.monotonic() - since


@pytest.mark.parametrize("sig", [signal.SIGKILL, signal.SIGSTOP], ids=["killed", "frozen"])
def test_a_timed_out_motion_of_a_vanished_holder_is_stopped(serve, sig: int) -> None:
    """The holder's move() timed out (no server thread waits on it any more) while the jaws kept moving; then
    the holder dies. Before: nothing of the server's own waited on that motion, so nothing stopped it."""
    server: ServeProcess = serve(f"g={sim('wsg50', scale=1)}", "--lease-timeout", str(LEASE))
    url = server.urls["g"]
    proc = _controller(["-c", TIMED_OUT, url], "timed out")
    try:
        with grippers.open(url) as watcher:
            assert watcher.state().moving  # the timeout did not stop the jaws
            proc.send_signal(sig)
            _stopped_within(watcher, time.monotonic(), LEASE + MARGIN)
            watcher.move(0.08)  # the lease is free again
    finally:
        proc.kill()
        proc.wait(5)


def test_the_servers_lease_timeout_bounds_a_frozen_holder_whatever_it_announced(serve) -> None:
    """The holder announces a 30 s Zenoh link lease, then freezes (SIGSTOP: its link stays open and silent).
    Before: its motion ran until Zenoh gave up on the link, 30 s later. Now --lease-timeout rules:
    the holder's heartbeats stop with it."""
    server: ServeProcess = serve(f"g={sim('wsg50', scale=1)}", "--lease-timeout", str(LEASE))
    url = server.urls["g"]
    proc = _controller([SILENT, url + "&lease=30", "0.2"], "moving")
    try:
        with grippers.open(url) as watcher:
            assert watcher.state().moving
            proc.send_signal(signal.SIGSTOP)
            took = _stopped_within(watcher, time.monotonic(), LEASE + MARGIN)
            assert took > LEASE * 0.5  # a silent holder is given its lease, not stopped at once
            watcher.move(0.08)
    finally:
        proc.kill()
        proc.wait(5)


@pytest.mark.parametrize("sig", [signal.SIGKILL, signal.SIGSTOP], ids=["killed", "frozen"])
def test_streams_of_a_dead_server_raise_connection_lost(serve, sig: int) -> None:
    """Before: the iterator raised GripperTimeout (no state within its wait) and a callback stream just went
    quiet. Now both learn ConnectionLost: the server's token goes with its session (at once when killed,
    after the server's link lease when frozen)."""
    server: ServeProcess = serve(f"g={sim('wsg50')}", "--lease-timeout", str(LEASE))
    g = grippers.open(server.urls["g"])
    seen = threading.Event()
    try:
        it = g.stream(rate_hz=20)
        cb = g.stream(rate_hz=20, callback=lambda state: seen.set())
        it.get(timeout=5)
        assert seen.wait(5)
        server.proc.send_signal(sig)
        killed = time.monotonic()
        with pytest.raises(ConnectionLost):
            while True:
                it.get(timeout=LEASE + 5.0)  # states already queued come first
        deadline = killed + LEASE + 5.0
        while cb.error is None and time.monotonic() < deadline:
            time.sleep(0.02)
        assert isinstance(cb.error, ConnectionLost)
        with pytest.raises(ConnectionLost):
            cb.get(timeout=1)
        with pytest.raises(ConnectionLost):
            g.state()
    finally:
        if sig == signal.SIGSTOP:
            server.proc.send_signal(signal.SIGCONT)
        g.close()
