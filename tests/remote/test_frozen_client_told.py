"""Issue 43 §6: a frozen (SIGSTOP) client was told "the server went away mid-motion" though the server still
served. Now it is told the lease ended: it was not heard from within the server's lease, so the server
stopped what it had set moving and freed the lease."""

from __future__ import annotations

import signal
import subprocess
import sys
import textwrap
import time

import pytest

import grippers

from .conftest import ROOT, ServeProcess, sim

pytestmark = pytest.mark.timeout(120)

MOVER = textwrap.dedent(
    """
    import sys, grippers
    g = grippers.open(sys.argv[1])
    g.home()
    print("moving", flush=True)
    try:
        g.move(g.limits.min_width + 0.001, g.limits.min_speed)
    except grippers.GripperError as exc:
        print(type(exc).__name__, exc, flush=True)
    """
)


def test_a_frozen_client_is_told_its_lease_ended_not_that_the_server_went_away(serve) -> None:
    server: ServeProcess = serve(f"g={sim('wsg50', scale=1)}", "--lease-timeout", "1")
    url = server.urls["g"] + "&lease=1"  # its Zenoh link lease: the server drops the frozen session too
    proc = subprocess.Popen([sys.executable, "-c", MOVER, url], cwd=ROOT, stdout=subprocess.PIPE, text=True)
    try:
        assert proc.stdout is not None
        assert proc.stdout.readline().strip() == "moving"
        time.sleep(0.5)
        proc.send_signal(signal.SIGSTOP)
        with grippers.open(server.urls["g"]) as watcher:
            deadline = time.monotonic() + 20
            while watcher.state().moving:  # the server's deadman stops the frozen holder's motion
                assert time.monotonic() < deadline, "never stopped"
                time.sleep(0.05)
            time.sleep(3.0)  # the frozen session's link lease runs out too
        proc.send_signal(signal.SIGCONT)
        out, _ = proc.communicate(timeout=60)
    finally:
        if proc.poll() is None:
            proc.kill()
            proc.communicate(timeout=10)
    assert "went away" not in out, out
    assert "CommandFailed" in out and "was not heard from within the server's lease" in out, out
