"""Safety: servers bind to loopback unless told otherwise, and no API path sends a force, current, speed or
width outside the profile's limits (observed where it lands: in the simulated device models)."""

from __future__ import annotations

import math
import os
import re
import select
import socket
import subprocess
import sys
from pathlib import Path

import pytest
from hypothesis import given
from hypothesis import strategies as st

import grippers
from grippers.drivers.errors import CommandFailed, GripperTimeout, LimitError
from grippers.drivers.stepfoc.sim import MsgModel
from grippers.drivers.stepfoc.uart_client import StepfocUart
from grippers.drivers.wsg.commands import decode_request
from grippers.drivers.wsg.sim import WsgModel, serve

ROOT = Path(__file__).resolve().parents[2]
LOOPBACK = "127.0.0.1"

# ------------------------------------------------------------------------------------------- bind addresses


@pytest.mark.parametrize("listen", ["tcp://:0", "udp://:0"])
def test_wsg_simulator_binds_to_loopback_when_no_host_is_named(listen: str) -> None:
    with serve(WsgModel(), listen) as server:
        assert server.address[0] == LOOPBACK
        assert LOOPBACK in server.url


def test_sim_url_gripper_serves_on_loopback() -> None:
    with grippers.open("sim://wsg50?time_scale=50") as g:
        assert g.simulator.address[0] == LOOPBACK
    with grippers.open("sim://wsg50?time_scale=50&transport=udp") as g:
        assert g.simulator.address[0] == LOOPBACK


def _listening_tcp(port: int) -> list[str]:
    """Local addresses (hex, /proc/net/tcp form) of sockets listening on ``port`` (state 0A)."""
    out = []
    for table in ("/proc/net/tcp", "/proc/net/tcp6"):
        try:
            lines = Path(table).read_text().splitlines()[1:]
        except OSError:
            continue
        for line in lines:
            fields = line.split()
            addr, hexport = fields[1].split(":")
            if int(hexport, 16) == port and fields[3] == "0A":
                out.append(addr)
    return out


def test_cli_simulator_binds_to_loopback_when_no_host_is_named() -> None:
    proc = subprocess.Popen(
        [sys.executable, "-m", "grippers", "sim", "wsg", "--listen", "tcp://:0"],
        cwd=ROOT,
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,
        text=True,
        env={**os.environ, "PYTHONUNBUFFERED": "1"},
    )
    try:
        assert proc.stdout is not None
        ready, _, _ = select.select([proc.stdout], [], [], 30)
        line = proc.stdout.readline() if ready else ""
        match = re.search(r"serving at wsg\+tcp://([^:/]+):(\d+)", line)
        assert match, line
        assert match.group(1) == LOOPBACK
        assert _listening_tcp(int(match.group(2))) == ["0100007F"]  # 127.0.0.1, not 0.0.0.0
        with socket.create_connection((LOOPBACK, int(match.group(2))), timeout=5):
            pass
    finally:
        proc.terminate()
        proc.wait(timeout=10)
        for stream in (proc.stdout, proc.stderr):
            if stream:
                stream.close()


# -------------------------------------------------------------------------------------------- the limits

finite_or_not = st.floats(allow_nan=True, allow_infinity=True)
# Mostly near and inside the limits (WSG 50: 0-0.11 m, 0.005-0.42 m/s, 5-80 N; MSG 150: 0-0.105 m,
# 0.001-0.1 m/s, 6-40 N), with the edges, beyond them, and non-finite values.
value = st.none() | st.floats(0.0, 0.12) | st.floats(0.0, 0.12) | st.floats(-0.2, 0.6) | finite_or_not
force_value = st.none() | st.floats(0.0, 90.0) | st.floats(0.0, 90.0) | st.floats(-20, 200) | finite_or_not


def tapped(url: str, method: str):
    """A homed ``url`` whose simulator model records the first argument of every call of its ``method``."""
    g = grippers.open(url)
    g.home()
    model = g.simulator.model
    seen: list = []
    original = getattr(model, method)

    def tap(item, *args, **kw):
        seen.append(item)
        return original(item, *args, **kw)

    setattr(model, method, tap)
    return g, seen


@pytest.fixture(scope="module")
def wsg_tapped():
    """A sim:// WSG 50 whose model records every request packet it receives."""
    g, seen = tapped("sim://wsg50?time_scale=1000", "handle")
    yield g, seen
    g.close()


@pytest.fixture(scope="module")
def msg_tapped():
    """A sim:// MSG 150 whose model records every 61 command it receives."""
    g, seen = tapped("sim://msg-150?time_scale=1000", "on_command")
    yield g, seen
    g.close()


def _within(x: float | None, lo: float, hi: float) -> bool:
    return x is None or (math.isfinite(x) and lo - 1e-9 <= x <= hi + 1e-9)


def _allowed(g, op: str, width, speed, force) -> bool:
    lim = g.limits
    ok = _within(speed, lim.min_speed, lim.max_speed) and (speed is None or speed > 0)
    if op != "release" or width is not None:
        ok = ok and width is not None and _within(width, lim.min_width, lim.max_width)
    if op == "grasp":
        ok = ok and _within(force, lim.min_force, lim.max_force)
    return ok


def _call(g, op: str, width, speed, force):
    if op == "move":
        return g.move(width, speed)
    if op == "grasp":
        return g.grasp(width, speed, force)
    return g.release(width, speed)


def _exercise(g, seen: list, op: str, width, speed, force, fuzz_count) -> int | None:
    """Call ``op``; None when it was refused with LimitError before anything was sent (checked here),
    otherwise the index in ``seen`` of the first thing it sent."""
    if op != "release" and width is None:
        width = 0.05
    start = len(seen)
    allowed = _allowed(g, op, width, speed, force)
    fuzz_count[f"safety {g.profile.family}: {'sent' if allowed else 'refused'}"] += 1
    if not allowed:
        with pytest.raises(LimitError):
            _call(g, op, width, speed, force)
        assert len(seen) == start, "something was sent before the LimitError"
        return None
    try:
        _call(g, op, width, speed, force)
    except (CommandFailed, GripperTimeout):
        pass  # refused, or answered late on a loaded machine: what matters is what was sent
    return start


def _f32_slack(x: float) -> float:
    return abs(x) * 1e-6 + 1e-6  # values travel as float32 (WSG manual 4.0.x §1)


@given(op=st.sampled_from(["move", "grasp", "release"]), width=value, speed=value, force=force_value)
def test_no_api_path_sends_a_wsg_value_outside_the_limits(
    wsg_tapped, op, width, speed, force, fuzz_count
) -> None:
    g, seen = wsg_tapped
    start = _exercise(g, seen, op, width, speed, force, fuzz_count)
    if start is None:
        return
    lim = g.limits
    bounds = {
        "width": (lim.min_width * 1000, lim.max_width * 1000),
        "speed": (lim.min_speed * 1000, lim.max_speed * 1000),
        "force": (lim.min_force, lim.max_force),
    }
    for packet in seen[start:]:
        fields = decode_request(packet.command, packet.payload)
        for name, (lo, hi) in bounds.items():
            if name in fields:
                x = fields[name]
                assert lo - _f32_slack(lo) <= x <= hi + _f32_slack(hi), (packet, name, x)


@given(op=st.sampled_from(["move", "grasp", "release"]), width=value, speed=value, force=force_value)
def test_no_api_path_sends_an_msg_value_outside_the_limits(
    msg_tapped, op, width, speed, force, fuzz_count
) -> None:
    g, seen = msg_tapped
    start = _exercise(g, seen, op, width, speed, force, fuzz_count)
    if start is None:
        return
    limit = g.profile.effective_max_current_ma
    assert len(seen) > start
    for cmd in seen[start:]:
        assert 0 <= cmd.position <= 255 and 0 <= cmd.speed <= 255
        assert 0 <= cmd.current_ma <= limit, cmd


def test_msg_driver_clamps_current_to_the_profile_limit(msg_can_sim, can_channel, msg_uart_sim) -> None:
    """The MSG firmware does not clamp its current (docs/protocols.md §2): the drivers do, before sending."""
    from grippers.drivers.stepfoc.can_client import StepfocBus

    server = msg_can_sim(MsgModel(node=0))
    with StepfocBus(interface="virtual", channel=can_channel) as bus:
        bus.node(0, current_limit_ma=700).command(10, 10, 2800, action=False)
    assert server.model.current_setpoint == 700
    uart = msg_uart_sim()
    with StepfocUart(uart.url, current_limit_ma=700) as client:
        assert client.current(2800) == 700
        with pytest.raises(LimitError):
            client.current(-1)
    assert uart.model.current_setpoint == 700


# ------------------------------------------------------------------------- a lowered limit is never dropped


def test_a_lowered_user_limit_holds_on_every_path_to_a_profile(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    """Issue 13 item 8: a user's file named like a built-in, lowering its force, is used by every lookup: by
    name, by alias, sim://, profile=, and a WSG opened by URL (profile from the device type). A 60 N grasp
    is refused before anything is sent, and the device never sees more than 25 N."""
    text = (ROOT / "profiles" / "wsg50.toml").read_text(encoding="utf-8")
    text = "\n".join(line for line in text.splitlines() if not line.startswith("aliases"))
    (tmp_path / "my-wsg.toml").write_text(
        text.replace("[wsg]", "[safety]\nmax_force_n = 25.0\n\n[wsg]"), encoding="utf-8"
    )
    (tmp_path / "zz-broken.toml").write_text("not toml", encoding="utf-8")  # an unrelated bad file
    monkeypatch.setenv("GRIPPERS_PROFILE_PATH", str(tmp_path))
    monkeypatch.setenv("XDG_CONFIG_HOME", str(tmp_path / "none"))
    for name in ("wsg50", "WSG 50", "wsg-50"):
        assert grippers.load_profile(name).limits().max_force == 25.0
    with grippers.open("sim://wsg50?time_scale=50") as sim:
        assert sim.limits.max_force == 25.0
        url = sim.simulator.url
        with grippers.open(url) as by_url, grippers.open(url, profile="WSG 50") as named:
            for g in (sim, by_url, named):
                assert g.limits.max_force == 25.0, g
                with pytest.raises(LimitError, match="force 60 N is outside"):
                    g.grasp(0.04, force=60)
            by_url.home()
            by_url.grasp(0.04)  # the default force (40 N in the built-in) is clamped to the lowered limit
            assert sim.simulator.model.force_limit <= 25.0
