"""Issue 33 on the served face: Ctrl-C stops what moves before serve exits; a mistyped endpoint and an
over-long label are usage errors said at once, in one line."""

from __future__ import annotations

import signal
import subprocess
import sys
import time

import pytest

import grippers
from grippers import URLError
from grippers.urls import with_params

from .conftest import ROOT, ServeProcess

pytestmark = pytest.mark.timeout(90)


@pytest.mark.parametrize(
    ("how", "sig"),
    [
        ("servo", signal.SIGINT),
        ("timed-out-move", signal.SIGINT),
        ("move", signal.SIGINT),
        ("move", signal.SIGTERM),
        ("move", signal.SIGHUP),
    ],
    ids=["servo", "timed-out-move", "move", "move-SIGTERM", "move-SIGHUP"],
)
@pytest.mark.parametrize("device", [("wsg50", {}), ("msg-150", {"transport": "pty"})], ids=["wsg", "msg"])
def test_ctrl_c_stops_the_jaws_before_serve_exits(
    serve, gripper_sim, how: str, sig: int, device: tuple
) -> None:
    """The simulator runs here, outside the server, so the jaws can be watched after serve is gone. Before:
    serve stopped only the motions its threads still waited on; a motion whose wait had timed out went on
    to its target after the exit. Issue 43 §1: SIGHUP (a closed terminal or ssh session) killed serve at once
    and the motion ran on unheld; SIGTERM stopped it but logged a thread traceback (``zenoh.ZError:
    Undeclared publisher``: a motion thread published its last state after the publisher was gone). Both
    are a server's ordinary end now: the same stops as Ctrl-C, exit 0."""
    device = gripper_sim(device[0], time_scale=1, **device[1])
    # The served device's own timeout leaves room for a CPU-starved simulator (the MSG's calibration reads).
    server: ServeProcess = serve(f"g={with_params(str(device), timeout=2)}")
    g = grippers.open(server.urls["g"])
    try:
        g.home()
        lo, hi = g.limits.min_width, g.limits.max_width
        far = hi - 0.001 if g.state().width < (lo + hi) / 2 else lo + 0.001  # homed open (WSG) or closed
        target, speed = far, g.limits.min_speed  # 20-40 s of travel
        if how == "servo":
            g.servo(target, speed)
        elif how == "move":
            g.move(target, speed, wait=False)
        else:
            with pytest.raises(grippers.GripperTimeout):
                g.move(target, speed, timeout=0.3)
        deadline = time.monotonic() + 10
        while not g.state().moving:
            assert time.monotonic() < deadline, "the motion never started"
            time.sleep(0.02)
        assert server.close(sig) == (130 if sig == signal.SIGINT else 0), server.stderr_text
    finally:
        g.close()
    assert "Traceback" not in server.stderr_text and "ZError" not in server.stderr_text, server.stderr_text
    if sig != signal.SIGINT:
        assert f"{signal.Signals(sig).name}: withdrawing and closing" in server.stderr_text
    with grippers.open(device) as direct:
        width = direct.state().width
        time.sleep(0.5)
        assert not direct.state().moving
        assert direct.state().width == pytest.approx(width, abs=1e-4)  # stopped, not still closing
        assert abs(width - target) > 0.03  # far from where it was going


def test_an_impossible_listen_port_is_a_usage_error() -> None:
    cmd = [sys.executable, "-m", "grippers", "serve", "sim://wsg50", "--listen", "tcp/127.0.0.1:99999"]
    out = subprocess.run(cmd, cwd=ROOT, capture_output=True, text=True, timeout=60)
    assert out.returncode == 2, out
    lines = out.stderr.strip().splitlines()
    assert len(lines) == 1 and "99999" in lines[0] and "0-65535" in lines[0], out.stderr
    assert ".rs" not in out.stderr  # no Rust source path
    assert "opened" not in out.stderr  # nothing was opened first


def test_zenohs_own_errors_lose_their_rust_source_paths() -> None:
    from grippers.remote.session import zenoh_message

    raw = (
        "Cannot create a new TLS listener on 127.0.0.1:0. Missing TLS private key. at /root/.cargo/git/x/"
        "zenoh-link-tls/src/utils.rs:532. at /root/.cargo/git/x/zenoh-link-tls/src/unicast.rs:426."
    )
    assert zenoh_message(RuntimeError(raw)) == (
        "Cannot create a new TLS listener on 127.0.0.1:0. Missing TLS private key."
    )


def test_a_label_over_256_characters_is_refused_at_open() -> None:
    """Before: accepted at open, then every command failed with "client and label must be short strings"."""
    with pytest.raises(URLError, match="label"):
        grippers.open("zenoh://g?connect=tcp/127.0.0.1:9&label=" + "x" * 257)
    with pytest.raises(URLError, match="0-65535"):
        grippers.open("zenoh://g?connect=tcp/127.0.0.1:70000")
