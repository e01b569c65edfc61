"""Issue 28 §2: the Robotiq family takes part in the commands through its backend's hooks, with no
``family ==`` branch in the CLI: ``grippers sim robotiq``, ``monitor`` dissecting its Modbus frames through
the TCP proxy, ``settings`` saying the family has none, and a bare serial port probed for Modbus slave 9."""

from __future__ import annotations

import json
import os
import re
import subprocess
import sys
from pathlib import Path

import pytest

import grippers
from grippers.cli import main

from ..selftest_verdicts import assert_passes_but_timed_speeds

ROOT = Path(__file__).resolve().parents[2]
pytestmark = pytest.mark.timeout(60)


def _grippers(*args: str) -> subprocess.Popen:
    return subprocess.Popen(
        [sys.executable, "-m", "grippers", *args],
        cwd=ROOT,
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,
        text=True,
        env={**os.environ, "PYTHONUNBUFFERED": "1"},
    )


def test_monitor_dissects_modbus_through_the_proxy(gripper_sim) -> None:
    device = gripper_sim("robotiq-2f85", activated=True)
    port = int(re.search(r":(\d+)", device.partition("?")[0].rpartition("@")[2]).group(1))
    monitor = _grippers("monitor", f"robotiq+tcp://127.0.0.1:{port}", "-n", "2", "--json")
    try:
        assert monitor.stderr is not None
        line = monitor.stderr.readline()
        listening = re.search(r"proxy listening on [^:]+:(\d+)", line)
        assert listening, line
        # Opening reads the status once through the proxy: one request and its response (-n 2 ends there).
        with grippers.open(f"robotiq+tcp://127.0.0.1:{listening.group(1)}?profile=robotiq-2f85") as g:
            assert g.profile.name == "robotiq-2f85"
        out, err = monitor.communicate(timeout=30)
    finally:
        monitor.kill()
        monitor.wait()
    records = [json.loads(text) for text in out.splitlines()]
    assert monitor.returncode == 0, err
    assert [r["protocol"] for r in records] == ["modbus", "modbus"]
    assert records[0]["direction"] == "host->gripper" and records[0]["node"] == 9
    assert records[1]["direction"] == "gripper->host" and "gSTA" in records[1]["fields"]


def test_settings_says_the_family_offers_none(gripper_sim, capsys) -> None:
    url = gripper_sim("robotiq-2f85", activated=True)
    assert main(["settings", url]) == 2
    assert "the robotiq backend offers no device settings" in capsys.readouterr().err


def test_sim_robotiq_serves_a_model_on_a_pty() -> None:
    sim = _grippers("sim", "robotiq", "--listen", "pty", "--model", "2f85", "--json")
    try:
        assert sim.stdout is not None
        doc = json.loads(sim.stdout.readline())
        url = doc["urls"][0]
        assert url.startswith("robotiq+serial://") and doc["what"] == "simulated 2F-85"
        with grippers.open(f"{url}{'&' if '?' in url else '?'}profile=robotiq-2f85") as g:
            assert g.info().family == "robotiq"
    finally:
        sim.terminate()
        sim.wait(10)


def test_probe_on_a_bare_serial_port_finds_the_gripper_at_slave_9(gripper_sim, capsys) -> None:
    url = gripper_sim("robotiq-2f85", transport="pty", activated=True)
    path = url.partition("://")[2].partition("?")[0]
    assert main(["probe", f"serial://{path}", "--timeout", "1", "--json"]) == 0
    doc = json.loads(capsys.readouterr().out)
    found = [g for g in doc["grippers"] if g["url"].startswith("robotiq+serial://")]
    assert len(found) == 1 and found[0]["model"] == "2F-85" and found[0]["profile"] == "robotiq-2f85", doc


def test_selftest_runs_and_says_the_family_offers_no_settings(capsys) -> None:
    code = main(["selftest", "sim://robotiq-2f85?time_scale=5&activated=true", "--yes", "--json"])
    out = capsys.readouterr().out
    assert code in (0, 3), out
    lines = assert_passes_but_timed_speeds(json.loads(out))
    assert lines["settings"]["note"] == "the robotiq backend offers no device settings", lines["settings"]
    assert "the robotiq gripper does not report its stroke" in lines["stroke"]["note"], lines["stroke"]
