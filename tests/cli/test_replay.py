"""Issue 16 §4: a capture saved by `monitor --write` becomes a fixture: `sim --replay` answers as the
captured session did, and reports (does not answer) a request that differs."""

from __future__ import annotations

import os
import re
import select
import signal
import subprocess
import sys
import threading
import time
from pathlib import Path

import can
import pytest

from grippers.cli import main
from grippers.drivers.captures import format_candump
from grippers.drivers.replay import Mismatch, Script, Step

ROOT = Path(__file__).resolve().parents[2]


def _popen(*args: str) -> subprocess.Popen:
    return subprocess.Popen(
        [sys.executable, "-m", "grippers", *args],
        cwd=ROOT,
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,
        text=True,
        env={**os.environ, "PYTHONUNBUFFERED": "1"},
    )


def _line(stream, pattern: str, timeout: float = 20.0) -> re.Match:
    end = time.monotonic() + timeout
    while time.monotonic() < end:
        ready, _, _ = select.select([stream], [], [], 0.2)
        if ready:
            line = stream.readline()
            m = re.search(pattern, line)
            if m:
                return m
    raise AssertionError(f"no line matching {pattern!r}")


def _stop(proc: subprocess.Popen) -> tuple[int, str]:
    proc.send_signal(signal.SIGTERM)
    _, err = proc.communicate(timeout=10)
    return proc.returncode, err


def test_script_rules() -> None:
    steps = [
        Step("a", "a", [(0.0, 1)]),
        Step("p", "p", [(0.0, 2)]),
        Step("p", "p", [(0.0, 3)]),
        Step("b", "b", [(0.1, 4)]),
    ]
    script = Script(steps)
    assert script.answer("a", "a") == [(0.0, 1)]
    assert script.answer("p", "p") == [(0.0, 2)]
    assert script.answer("b", "b") == [(0.1, 4)]  # the second poll of the capture was skipped
    assert script.answer("b", "b") == [(0.1, 4)]  # a repeat of the last request: same answer
    assert script.repeated == 1 and script.done
    outcome = script.answer("c", "c")
    assert isinstance(outcome, Mismatch) and "after the end" in str(outcome)
    fresh = Script([Step("a", "a"), Step("b", "b")])
    wrong = fresh.answer("b", "b")
    assert isinstance(wrong, Mismatch) and "expected a, got b" in str(wrong) and fresh.next == 0


def test_wsg_capture_replays_the_session(tmp_path: Path, cli, sim_process) -> None:
    sim = sim_process("wsg", "--listen", "tcp://127.0.0.1:0", "--time-scale", "50")
    port = int(sim.url.rsplit(":", 1)[1])
    capture = tmp_path / "session.hex"
    proxy = _popen("monitor", "--proxy", "127.0.0.1:0", "--to", f"127.0.0.1:{port}", "--write", str(capture))
    try:
        proxy_port = _line(proxy.stderr, r"proxy listening on 127\.0\.0\.1:(\d+)").group(1)
        live = cli("home", f"wsg+tcp://127.0.0.1:{proxy_port}", "--json").json()
        time.sleep(0.2)
    finally:
        _stop(proxy)
    assert capture.read_text().count("\n") > 10
    replay = _popen(
        "sim", "wsg", "--replay", str(capture), "--listen", "tcp://127.0.0.1:0", "--time-scale", "50"
    )
    try:
        url = _line(replay.stdout, r"serving at (\S+)").group(1)
        again = cli("home", url, "--json").json()
        assert again["state"] == live["state"] and again["ok"]
        other = cli("move", url, "20", "--timeout", "0.5")  # not in the capture
        assert other.returncode == 1
    finally:
        code, err = _stop(replay)
    assert code == 1  # a mismatch makes the replay fail, for CI
    assert "request after the end of the capture" in err and "not answered" in err


def test_stepfoc_capture_replays_on_a_bus(tmp_path: Path, capsys) -> None:
    """Record a client session against the simulator on a virtual bus (a bus listener writes the candump
    log, as `monitor -i -c --write` does), then replay it on another bus and run the same command."""
    from grippers.backends import get_backend
    from grippers.profiles import load_profile
    from grippers.settings import Settings

    channel = f"replay-rec-{time.monotonic_ns()}"
    lines: list[str] = []
    backend = get_backend("stepfoc")
    model = backend.sim_model(load_profile("msg-150"), 0, None)
    server = backend.serve([model], f"can://virtual/{channel}", Settings("x", {}, {}))
    tap = can.Bus(interface="virtual", channel=channel)
    stop = threading.Event()

    def listen() -> None:
        while not stop.is_set():
            msg = tap.recv(0.05)
            if msg is not None:
                lines.append(
                    format_candump(
                        msg.timestamp,
                        channel,
                        msg.arbitration_id,
                        bytes(msg.data),
                        is_remote=msg.is_remote_frame,
                    )
                )

    thread = threading.Thread(target=listen)
    thread.start()
    try:
        assert main(["state", f"stepfoc+can://virtual/{channel}?node=0", "--json"]) == 0
        live = capsys.readouterr().out
        time.sleep(0.2)
    finally:
        stop.set()
        thread.join(5)
        tap.shutdown()
        server.close()
    capture = tmp_path / "msg.log"
    capture.write_text("\n".join(lines) + "\n")

    from grippers.drivers.stepfoc.sim import replay

    script = replay.stepfoc_script(capture.read_bytes(), str(capture))
    channel2 = f"replay-play-{time.monotonic_ns()}"
    player = replay.StepfocReplayServer(script, "virtual", channel2)
    try:
        assert main(["state", f"stepfoc+can://virtual/{channel2}?node=0", "--json"]) == 0
        again = capsys.readouterr().out
    finally:
        player.close()
    strip = re.compile(r'"time": [0-9.]+, |"target": "[^"]+", ')
    assert strip.sub("", again) == strip.sub("", live)
    assert not script.mismatches and script.answered >= 2


def test_replay_needs_a_capture_with_directions(tmp_path: Path, cli) -> None:
    capture = tmp_path / "nodir.hex"
    capture.write_text("AA AA AA 50 00 00 DB 87\n")
    r = cli("sim", "wsg", "--replay", str(capture), "--listen", "tcp://127.0.0.1:0")
    assert r.returncode == 2 and "direction" in r.one_error_line()


@pytest.mark.parametrize("family", ["wsg", "msg"])
def test_replay_of_a_missing_file_is_a_usage_error(family: str, cli, tmp_path: Path) -> None:
    r = cli("sim", family, "--replay", str(tmp_path / "none.log"))
    assert r.returncode == 2 and "none.log" in r.one_error_line()


def test_replay_stops_promptly_on_sigterm_with_a_client_connected(tmp_path: Path) -> None:
    import socket

    capture = tmp_path / "one.hex"
    capture.write_text("(1.0) > AA AA AA 50 00 00 DB 87\n(1.1) < AA AA AA 50 02 00 00 00 00 00\n")
    replay = _popen("sim", "wsg", "--replay", str(capture), "--listen", "tcp://127.0.0.1:0")
    url = _line(replay.stdout, r"serving at (\S+)").group(1)
    client = socket.create_connection(("127.0.0.1", int(url.rsplit(":", 1)[1])))
    try:
        replay.send_signal(signal.SIGTERM)
        replay.communicate(timeout=30)  # it ends at all (the promptness is checked in process, below)
    finally:
        client.close()
        if replay.poll() is None:
            replay.kill()
            replay.wait(5)
    assert replay.returncode == 0


def test_replay_server_close_ends_its_accept_thread_with_a_client_connected() -> None:
    """The accept loop used to block in accept(), which close() does not wake on Linux: close() waited its
    2 s and returned with the thread still blocked (for good). Now close() returns with the thread ended."""
    import socket

    from grippers.drivers.wsg.sim.replay import WsgReplayServer, wsg_script

    script = wsg_script(
        b"(1.0) > AA AA AA 50 00 00 DB 87\n(1.1) < AA AA AA 50 02 00 00 00 00 00\n", "one.hex"
    )
    server = WsgReplayServer(script, "127.0.0.1", 0)
    client = socket.create_connection(("127.0.0.1", int(server.url.rsplit(":", 1)[1])))
    try:
        deadline = time.monotonic() + 30.0
        while not server._conns:  # accepted: the loop goes back to accept() for the next client
            assert time.monotonic() < deadline
            time.sleep(0.01)
        time.sleep(0.2)
        server.close()
        assert not server._thread.is_alive()
    finally:
        client.close()
