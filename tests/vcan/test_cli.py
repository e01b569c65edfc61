"""The CLI on a SocketCAN bus: ``grippers sim`` of both families, ``probe`` of a bare bus, ``state``,
``monitor`` and ``monitor --write`` (read back by ``monitor FILE``). Every process is a real subprocess.

MSG nodes 14 and 15; WSG ids 0x310/0x311. Skipped without vcan0 (run ``scripts/run-vcan-tests.sh``).
"""

from __future__ import annotations

import json
import queue
import time
from collections.abc import Callable
from pathlib import Path

import can
import pytest

from grippers.drivers.stepfoc.can_protocol import Cmd, pack_id

from .conftest import Proc, run_cli

pytestmark = pytest.mark.vcan


def _wait_for_line(proc: Proc, poke: Callable[[], None], timeout: float) -> str:
    """Poke the bus until the monitor prints a line: then it is surely listening (no guessing how long a
    subprocess takes to start on a slow machine)."""
    deadline = time.monotonic() + timeout
    while time.monotonic() < deadline:
        poke()
        try:
            return proc.lines.get(timeout=0.2)
        except queue.Empty:
            pass
    raise AssertionError(f"the monitor printed nothing within {timeout:g} s")


def test_msg_sim_probe_state_and_monitor_write(
    vcan: str, grippers_proc: Callable[..., Proc], tmp_path: Path
) -> None:
    sim = grippers_proc("sim", "msg", "--listen", f"can://socketcan/{vcan}?node=14,15", "--time-scale", "50")
    assert f"stepfoc+can://socketcan/{vcan}?node=14" in sim.first
    log = tmp_path / "session.log"
    monitor = grippers_proc(
        "monitor", "-i", "socketcan", "-c", vcan, "--protocol", "stepfoc", "--json", "--write", str(log),
        "--duration", "300", first_line=False,
    )  # fmt: skip
    with can.Bus(interface="socketcan", channel=vcan) as raw:
        # an empty 61 is a poll (docs/protocols.md §2): node 14 answers, the monitor prints both frames
        poll = can.Message(arbitration_id=pack_id(14, Cmd.GRIPPER_COMMAND), data=b"", is_extended_id=False)
        first = json.loads(_wait_for_line(monitor, lambda: raw.send(poll), 60))
        assert first["protocol"] == "stepfoc"

    probe = run_cli("probe", f"can://socketcan/{vcan}", "--timeout", "1", "--json")
    assert probe.returncode == 0, probe.stderr
    found = {g["url"] for g in json.loads(probe.stdout)["grippers"]}
    assert {f"stepfoc+can://socketcan/{vcan}?node={n}" for n in (14, 15)} <= found

    state = run_cli("state", f"stepfoc+can://socketcan/{vcan}?node=15", "--json", "--timeout", "2")
    assert state.returncode == 0, state.stderr
    assert "width_mm" in state.stdout

    out, err = monitor.stop()
    assert monitor.proc.returncode in (0, 130), err
    live = [first] + [json.loads(line) for line in out.splitlines() if line.strip()]
    seen = {(d["node"], d["command"]) for d in live}
    assert {(15, "gripper_command"), (15, "gripper_status"), (14, "gripper_status")} <= seen
    # the --write file is a candump log that monitor reads back to the same frames
    written = log.read_text().splitlines()
    assert written and all(f" {vcan} " in line for line in written)
    again = run_cli("monitor", str(log), "--protocol", "stepfoc", "--json")
    assert again.returncode == 0, again.stderr
    replayed = [json.loads(line) for line in again.stdout.splitlines() if line.strip()]
    assert len(written) >= len(live) - 1  # (SIGINT may end the process between a line and its write)
    assert [(d["id"], d["raw"]) for d in replayed][: len(live) - 1] == [(d["id"], d["raw"]) for d in live][
        : len(live) - 1
    ]


def test_wsg_sim_over_can_probe_and_state(vcan: str, grippers_proc: Callable[..., Proc]) -> None:
    listen = f"can://socketcan/{vcan}?send_id=0x310&recv_id=0x311"
    sim = grippers_proc("sim", "wsg", "--listen", listen, "--time-scale", "50")
    url = f"wsg+can://socketcan/{vcan}?send_id=0x310&recv_id=0x311"
    assert url in sim.first
    probe = run_cli("probe", url, "--timeout", "1", "--json")
    assert probe.returncode == 0, probe.stderr
    [gripper] = json.loads(probe.stdout)["grippers"]
    assert gripper["family"] == "wsg" and gripper["url"] == url
    state = run_cli("state", url, "--json", "--timeout", "2")
    assert state.returncode == 0, state.stderr
