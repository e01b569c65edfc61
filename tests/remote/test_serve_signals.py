"""Issue 43 §1 on the served face: SIGHUP (a closed terminal or ssh session) to ``grippers serve`` stops the
clients' motions as SIGTERM does (it exited at once and a client's motion ran on with nobody holding it),
and SIGTERM logs no thread traceback (``zenoh.ZError: Undeclared publisher`` from a motion thread that
published its last state after the publisher was gone)."""

from __future__ import annotations

import signal
import time

import pytest

import grippers

from .conftest import ServeProcess

pytestmark = pytest.mark.timeout(90)


@pytest.mark.parametrize("sig", [signal.SIGTERM, signal.SIGHUP], ids=["SIGTERM", "SIGHUP"])
@pytest.mark.parametrize("device", [("wsg50", {}), ("msg-150", {"transport": "pty"})], ids=["wsg", "msg"])
def test_sigterm_and_sighup_stop_the_jaws_before_serve_exits(
    serve, gripper_sim, sig: int, device: tuple
) -> None:
    device = gripper_sim(device[0], time_scale=1, **device[1])
    server: ServeProcess = serve(f"g={device}")
    g = grippers.open(server.urls["g"])
    try:
        g.home()
        lo, hi = g.limits.min_width, g.limits.max_width
        target = hi - 0.001 if g.state().width < (lo + hi) / 2 else lo + 0.001
        g.move(target, g.limits.min_speed, wait=False)  # 20-40 s of travel
        deadline = time.monotonic() + 10
        while not g.state().moving:
            assert time.monotonic() < deadline, "the motion never started"
            time.sleep(0.02)
        assert server.close(sig) == 0, server.stderr_text  # a server's ordinary end
    finally:
        g.close()
    assert "Traceback" not in server.stderr_text and "ZError" not in server.stderr_text, server.stderr_text
    assert f"{signal.Signals(sig).name}: withdrawing and closing" in server.stderr_text
    with grippers.open(device) as direct:
        width = direct.state().width
        time.sleep(0.5)
        assert not direct.state().moving
        assert direct.state().width == pytest.approx(width, abs=1e-4)
        assert abs(width - target) > 0.03
