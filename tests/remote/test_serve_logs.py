"""Issue 22 §2-3 for ``grippers serve``: exit 130 on Ctrl-C; log lines with a time stamp and
a level on stderr or in ``--log-file``; a gripper lost and back again is said, and served again."""

from __future__ import annotations

import re
import signal
import socket
import subprocess
import sys
import time
from pathlib import Path

import pytest

import grippers
from grippers import ConnectionLost

from .conftest import ROOT, ServeProcess, sim

pytestmark = pytest.mark.timeout(90)

STAMPED = r"^\d{4}-\d\d-\d\d \d\d:\d\d:\d\d,\d{3} (INFO|WARNING|ERROR) grippers\.remote: "


def test_ctrl_c_exits_130_and_logs_are_stamped_on_stderr(serve) -> None:
    server: ServeProcess = serve(f"g={sim('wsg50')}")
    with grippers.open(server.urls["g"] + "&label=bench") as g:
        g.home()
    with grippers.open(server.urls["g"]) as other:  # close() gave the lease back
        deadline = time.monotonic() + 20
        while True:
            try:
                other.acquire_control()
                break
            except grippers.AccessDenied:
                assert time.monotonic() < deadline
                time.sleep(0.05)
    assert server.close(signal.SIGINT) == 130
    err = server.stderr_text
    assert re.search(STAMPED + r"serving g ", err, re.M), err
    assert re.search(STAMPED + r"g: control lease taken by bench ", err, re.M), err  # issue 22 §3
    assert re.search(STAMPED + r"g: control lease released by client \w+", err, re.M), err
    assert "vanished" not in err  # a normal close() is not a vanished holder (issue 31 §2)
    assert err.rstrip().endswith("grippers serve: interrupted"), err


def _free_port() -> int:
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return int(s.getsockname()[1])


def _simulator(port: int) -> subprocess.Popen[str]:
    proc = subprocess.Popen(
        [sys.executable, "-m", "grippers", "sim", "wsg", "--listen", f"tcp://127.0.0.1:{port}"]
        + ["--time-scale", "50"],
        cwd=ROOT,
        stdout=subprocess.PIPE,
        stderr=subprocess.DEVNULL,
        text=True,
    )
    assert proc.stdout is not None and "serving at" in proc.stdout.readline()
    return proc


def _wait_for(path: Path, text: str, bound: float = 20.0) -> str:
    deadline = time.monotonic() + bound
    while time.monotonic() < deadline:
        log = path.read_text() if path.exists() else ""
        if text in log:
            return log
        time.sleep(0.05)
    raise AssertionError(f"{text!r} not logged; log: {log!r}")


def test_a_lost_gripper_is_said_and_served_again_when_back(tmp_path: Path) -> None:
    port = _free_port()
    log = tmp_path / "serve.log"
    device = _simulator(port)
    url = f"wsg+tcp://127.0.0.1:{port}?reconnect=true&heartbeat_s=0.2&reconnect_backoff_max_s=0.5"
    server = ServeProcess(f"g={url}", "--log-file", str(log))
    try:
        with grippers.open(server.urls["g"]) as g:
            g.home()
        device.kill()
        device.wait(5)
        text = _wait_for(log, "g: gripper lost")
        assert re.search(STAMPED + r"g: gripper lost", text, re.M), text
        with pytest.raises(ConnectionLost), grippers.open(server.urls["g"]) as g:
            g.state()
        device = _simulator(port)
        text = _wait_for(log, "g: gripper back")
        assert re.search(r"^\S+ \S+ WARNING grippers\.remote: g: gripper back", text, re.M), text
        with grippers.open(server.urls["g"]) as g:
            assert not g.state().referenced  # a fresh device
            g.home()
            assert g.move(0.05).width == pytest.approx(0.05, abs=0.001)
        assert server.close(signal.SIGTERM) == 0  # SIGTERM: a clean stop, not an interruption
        assert "gripper lost" not in server.stderr_text  # the log went to the file
    finally:
        server.close()
        device.kill()
        device.wait(5)
