"""The control lease: many observers, one controller; stop and fast_stop from anyone; a holder that dies
mid-motion has its motion stopped and its lease freed."""

from __future__ import annotations

import signal
import subprocess
import sys
import time

import pytest

import grippers
from grippers import AccessDenied

from .conftest import ROOT, ServeProcess, sim

pytestmark = pytest.mark.timeout(60)


def test_two_clients_one_lease(serve) -> None:
    server = serve(f"g={sim('wsg50')}")
    url = server.urls["g"]
    with grippers.open(url) as a, grippers.open(url + "&label=teleop") as b:
        a.home()  # the first motion command takes the lease
        with pytest.raises(AccessDenied, match="held by") as denied:
            b.move(0.05)
        assert isinstance(denied.value, grippers.GripperError) and denied.value.holder
        with pytest.raises(AccessDenied):
            b.acknowledge()  # changes the device: refused too, without taking the lease
        assert b.state().referenced  # observing is always allowed
        handle = a.move(0.01, a.limits.min_speed, wait=False)
        time.sleep(0.05)
        b.stop()  # stop is accepted from every client, always
        with pytest.raises(grippers.GripperError):
            handle.wait(5)  # the device aborted the motion
        b.fast_stop()
        a.acknowledge()
        a.release_control()
        with b.control():  # explicit: taken now, freed at the end
            b.move(0.06)
            with pytest.raises(AccessDenied, match="teleop"):
                a.move(0.05)
        a.move(0.05)  # free again: a takes it
    # Closing the holder frees the lease: a new client commands at once.
    with grippers.open(url) as c:
        assert c.move(0.04).width == pytest.approx(0.04, abs=0.002)


CONTROLLER = str(ROOT / "benchmarks" / "moving_controller.py")  # shared with the lease benchmark


@pytest.mark.parametrize("sig", [signal.SIGKILL, signal.SIGSTOP], ids=["killed", "frozen-silent-link"])
def test_controller_killed_mid_motion_is_stopped(serve, sig: int) -> None:
    """SIGKILL closes the controller's connection at once; SIGSTOP leaves it open and silent, like a cut
    cable, so only the link lease the client announced (1 s by default) can tell."""
    lease_timeout = 1.0
    server: ServeProcess = serve(f"g={sim('wsg50', scale=1)}", "--lease-timeout", str(lease_timeout))
    url = server.urls["g"]
    proc = subprocess.Popen(
        [sys.executable, CONTROLLER, url, "0.2"], cwd=ROOT, stdout=subprocess.PIPE, text=True
    )
    try:
        assert proc.stdout is not None and proc.stdout.readline().strip() == "moving"
        with grippers.open(url) as watcher:
            assert watcher.state().moving
            with pytest.raises(AccessDenied):
                watcher.move(0.05)
            proc.send_signal(sig)
            killed = time.monotonic()
            while watcher.state().moving:
                assert time.monotonic() - killed < lease_timeout + 1.0, "motion still running"
                time.sleep(0.01)
            stopped_after = time.monotonic() - killed
            width = watcher.state().width
            assert width > watcher.limits.min_width + 0.05  # it stopped far from the target (22 s away)
            time.sleep(0.2)
            assert watcher.state().width == pytest.approx(width, abs=1e-4)
            # The lease is free again: the watcher takes it.
            watcher.move(0.08)
        assert stopped_after < lease_timeout + 0.5
    finally:
        proc.kill()
        proc.wait(5)


def test_server_shutdown_stops_a_running_motion(serve) -> None:
    server: ServeProcess = serve(f"g={sim('wsg50', scale=1)}")
    g = grippers.open(server.urls["g"])
    try:
        g.home()
        handle = g.move(g.limits.min_width + 0.001, g.limits.min_speed, wait=False)
        time.sleep(0.1)
        started = time.monotonic()
        # Ctrl-C: motion stopped, grippers closed, and the exit every command makes (issue 22 §2)
        assert server.close(signal.SIGINT) == 130
        assert time.monotonic() - started < 5.0  # not the 20 s the motion would take
        assert "grippers serve: interrupted" in server.stderr_text
        with pytest.raises(grippers.GripperError):
            handle.wait(5)
    finally:
        g.close()
