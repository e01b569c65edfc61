"""Issue 43 §1 and issue 39 §2: every way a command ends stops the jaws first (grippers/cli/signals.py).

SIGTERM (``kill``) and SIGHUP (a closed terminal or ssh session) to a command that moves a gripper killed it
at once and the jaws went on; now each stops every gripper the command opened, finishes its files and exits
128 + n. Each test runs the real CLI in a subprocess against a simulator in this process, over a real
transport, so the jaws can be watched after the command is gone. The simulator's clock is held from the
moment the jaws are seen moving until the signal has been sent (tests/simhold.py): the motion is surely
running when the signal arrives, however busy the machine.
"""

from __future__ import annotations

import json
import os
import signal
import subprocess
import sys
import time
from pathlib import Path
from typing import Any

import pytest

import grippers

from ..simhold import held, step_until

ROOT = Path(__file__).resolve().parents[2]
SIGNALS = [signal.SIGINT, signal.SIGTERM, signal.SIGHUP]
IDS = ["SIGINT", "SIGTERM", "SIGHUP"]
SLOW = 0.2  # simulated seconds per wall-clock second: a 5 mm/s WSG motion crawls at 1 mm/s

pytestmark = pytest.mark.timeout(120)


def _start(*argv: str) -> subprocess.Popen[str]:
    return subprocess.Popen(
        [sys.executable, "-m", "grippers", *argv],
        cwd=ROOT,
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,
        text=True,
        env={**os.environ, "PYTHONUNBUFFERED": "1"},
    )


def _ended(proc: subprocess.Popen[str]) -> tuple[int, str, str]:
    try:
        out, err = proc.communicate(timeout=60)
    finally:
        if proc.poll() is None:
            proc.kill()
            proc.communicate(timeout=10)
    return proc.returncode, out, err


def _signal_once_moving(url: Any, proc: subprocess.Popen[str], sig: int) -> None:
    """Hold the device the moment a motion is under way (seen over a connection of our own), send ``sig``,
    then let the clock run: the stop must come from the signal, not from the end of the motion."""
    with grippers.open(url) as watch, held(url, creep=0.001) as clock:

        def moving() -> bool:
            assert proc.poll() is None, proc.communicate()
            return bool(watch.state().moving)

        deadline = time.monotonic() + 60
        while not moving():  # the command's own start-up, in wall-clock time; the device stands still
            assert time.monotonic() < deadline, "the command never set the jaws moving"
            time.sleep(0.01)
        step_until(clock, moving, "motion under way")
        proc.send_signal(sig)


def _assert_still(url: str, far_from_mm: float | None = None) -> None:
    """The jaws stand still after the command is gone, with the clock running."""
    with grippers.open(url) as g:
        first = g.state()
        time.sleep(1.0)  # 1 simulated second at least: 1 mm at the slowest speed here
        later = g.state()
    assert not later.moving, later
    assert later.width == pytest.approx(first.width, abs=2e-4), (first.width, later.width)
    if far_from_mm is not None:
        assert abs(later.width * 1000 - far_from_mm) > 5, later.width


def _expect(code: int, err: str, sig: int) -> None:
    assert code == 128 + sig, err
    assert "Traceback" not in err, err
    last = err.strip().splitlines()[-1]
    said = "interrupted" if sig == signal.SIGINT else f"interrupted by {signal.Signals(sig).name}"
    assert last.endswith(said), err


@pytest.fixture
def wsg(gripper_sim: Any) -> Any:
    url = gripper_sim("wsg50", time_scale=SLOW)
    with grippers.open(url) as g:
        g.home()
        g.move(0.06, 0.4)
    return url


@pytest.mark.parametrize("sig", SIGNALS, ids=IDS)
@pytest.mark.parametrize(
    ("argv", "target_mm"),
    [
        (("move", "10", "--speed", "5"), 10.0),
        (("grasp", "10", "--speed", "5", "--force", "20"), 10.0),
        (("release", "100", "--speed", "5"), 100.0),
        (("home",), 110.0),
    ],
    ids=["move", "grasp", "release", "home"],
)
def test_a_signal_mid_motion_stops_the_jaws(
    wsg: Any, argv: tuple[str, ...], target_mm: float, sig: int
) -> None:
    proc = _start(argv[0], wsg, *argv[1:])
    _signal_once_moving(wsg, proc, sig)
    code, _, err = _ended(proc)
    _expect(code, err, sig)
    _assert_still(wsg, far_from_mm=target_mm)


@pytest.mark.parametrize("sig", SIGNALS, ids=IDS)
@pytest.mark.parametrize("ext", [".mcap", ".csv"])
def test_record_do_on_a_signal_stops_the_jaws_and_finishes_the_file(
    wsg: Any, tmp_path: Path, sig: int, ext: str
) -> None:
    if ext == ".mcap":
        pytest.importorskip("mcap")
    out = tmp_path / f"run{ext}"
    proc = _start("record", wsg, "-o", str(out), "--do", "move 10 --speed 5")
    _signal_once_moving(wsg, proc, sig)
    code, _, err = _ended(proc)
    _expect(code, err, sig)
    _assert_still(wsg, far_from_mm=10.0)
    from grippers.recording import load

    recording = load(out)
    assert recording.cut is None, recording.cut  # finished, never cut inside a record
    phases = [r["phase"] for r in recording.rows if r["kind"] == "command"]
    assert phases[:1] == ["start"] and "failed" in phases, phases  # the motion ended by the stop, stamped


@pytest.mark.parametrize("sig", SIGNALS, ids=IDS)
def test_selftest_on_a_signal_stops_the_jaws(gripper_sim: Any, sig: int) -> None:
    url = gripper_sim("wsg50", time_scale=SLOW)
    proc = _start("selftest", url, "--yes", "--time-scale", str(SLOW))
    _signal_once_moving(url, proc, sig)
    code, _, err = _ended(proc)
    _expect(code, err, sig)
    _assert_still(url)


@pytest.mark.parametrize("family", ["msg-150", "robotiq-2f85", "wsg50"])
def test_a_motion_that_times_out_leaves_the_jaws_still(gripper_sim: Any, family: str) -> None:
    """Issue 39 §2: ``grippers move M 100 --speed 2.5 --motion-timeout 0.5`` exited 1 and an MSG or a
    Robotiq went on to 100 mm; the WSG stopped."""
    transport = {"msg-150": {"transport": "pty"}}.get(family, {})
    url = gripper_sim(family, time_scale=1, **transport)
    with grippers.open(url) as g:
        g.home()
        closed = g.limits.min_width
        g.move(closed + 0.002)
        slow = max(g.limits.min_speed, 0.0025)
    r = subprocess.run(
        [
            sys.executable,
            "-m",
            "grippers",
            "move",
            url,
            "50",
            "--speed",
            f"{slow * 1000:g}",
            "--motion-timeout",
            "0.5",
            "--json",
        ],
        cwd=ROOT,
        capture_output=True,
        text=True,
        timeout=60,
    )
    assert r.returncode == 1, (r.stdout, r.stderr)
    _assert_still(url, far_from_mm=50.0)


@pytest.mark.parametrize("sig", [signal.SIGINT, signal.SIGTERM], ids=["SIGINT", "SIGTERM"])
def test_a_signal_after_the_command_ended_keeps_its_status(gripper_sim: Any, sig: int) -> None:
    """Issue 43 §9: Ctrl-C 40-110 ms after the summary ended with SIGINT's status, or exit 0 and a
    traceback from the interpreter's shutdown. The signal lands here after main() has returned, in the exit
    itself (an atexit hook sends it); the command's own status and output stand."""
    script = (
        "import atexit, os, signal, sys, time\n"
        "from grippers.cli import main\n"
        "def late():\n"
        f"    os.kill(os.getpid(), {int(sig)})\n"
        "    time.sleep(1)\n"
        "atexit.register(late)\n"
        "sys.exit(main())\n"
    )
    url = gripper_sim("wsg50", time_scale=50)
    r = subprocess.run(
        [sys.executable, "-c", script, "state", url, "--json"],
        cwd=ROOT,
        capture_output=True,
        text=True,
        timeout=60,
    )
    assert r.returncode == 0, r.stderr
    assert "Traceback" not in r.stderr and "KeyboardInterrupt" not in r.stderr, r.stderr
    assert "state" in json.loads(r.stdout)  # the document was printed whole
