"""Issue 19 §3: ``grippers selftest URL`` against both simulators over real transports.

The simulators run faster than real time; the selftest is told the scale (``time_scale`` of a sim:// URL, or
``--time-scale``) and turns wall-clock times into device times. A run whose speed map is off must say so:
WARN on the speed lines and exit code 3. The MSG tests do not assume what the simulator's speed model is
today (another change makes it follow the firmware): they measure it, write the measured profile, and check
that the written profile passes and that a profile whose map is off by 3x does not.
"""

from __future__ import annotations

import json
import math
import time
import tomllib
from pathlib import Path

import pytest

from grippers.backends import get_backend
from grippers.cli import main
from grippers.cli.schemas import validate
from grippers.cli.selftest_checks import (
    MAX_UNCERTAINTY,
    SpeedMeasurement,
    fit_speed,
    fitted_speed_map,
    speed_verdict,
)
from grippers.profiles import load_file, load_profile
from grippers.settings import Settings

WSG_SCALE = "2"  # slow enough that a loaded machine still samples every move many times
MSG_SCALE = "5"


def _speed_lines(doc: dict) -> list[dict]:
    return [ln for ln in doc["lines"] if ln["check"].startswith("speed ")]


def test_refuses_without_a_terminal_or_yes(cli) -> None:
    r = cli("selftest", f"sim://wsg50?time_scale={WSG_SCALE}")
    assert r.returncode == 2 and "--yes" in r.one_error_line()


def test_wsg_passes_and_writes_a_profile_that_loads(cli, tmp_path: Path) -> None:
    out = tmp_path / "wsg50-bench.toml"
    r = cli(
        "selftest",
        f"sim://wsg50?time_scale={WSG_SCALE}",
        "--yes",
        "--json",
        "--write-profile",
        str(out),
        timeout=90,
    )
    doc = r.json()
    assert r.returncode == 0, r.stdout + r.stderr
    assert doc["ok"] and doc["warnings"] == 0 and doc["family"] == "wsg"
    checks = [ln["check"] for ln in doc["lines"]]
    for wanted in (
        "home (1st)",
        "home (2nd)",
        "stroke",
        "close without a part",
        "soft limits",
        "faults after",
    ):
        assert wanted in checks
    assert len(_speed_lines(doc)) == 3
    assert "keep the jaws EMPTY" in r.stderr  # it said what it would do
    written = load_file(out)
    assert written.name == "wsg50-measured" and written.mechanics.stroke_mm == 110.0
    assert tomllib.loads(out.read_text())["extends"] == "wsg50"


def test_wsg_speed_off_is_a_warn_and_exit_3(cli) -> None:
    # The simulator runs 2x real time, the selftest is told 1x: every speed reads twice what was asked, as
    # on a unit whose speeds do not match its profile.
    r = cli(
        "selftest",
        f"sim://wsg50?time_scale={WSG_SCALE}",
        "--time-scale",
        "1",
        "--yes",
        "--json",
        timeout=90,
    )
    assert r.returncode == 3, r.stdout + r.stderr
    doc = r.json()
    assert not doc["ok"] and doc["warnings"] >= 3
    speeds = _speed_lines(doc)
    assert len(speeds) == 3 and all(ln["verdict"] == "WARN" for ln in speeds)
    assert all(1.6 < ln["value"] / float(ln["check"].split()[1]) < 2.5 for ln in speeds)


def test_wsg_table_says_warn(cli) -> None:
    r = cli("selftest", f"sim://wsg50?time_scale={WSG_SCALE}", "--time-scale", "1", "--yes", timeout=90)
    assert r.returncode == 3
    assert "WARN" in r.stdout and "verdict" in r.stdout.splitlines()[0]
    assert r.stdout.rstrip().splitlines()[-1].endswith("WARN")


@pytest.fixture
def fresh_msg():
    """A new stock msg-150 simulator on its own python-can virtual bus, 5x real time, per call.

    One per selftest run: a second session on the same node meets the node-wide same-command latch and the
    early end of a recalibration (issue 19 §2, fixed in the MSG client, not here); the selftest reports
    those as WARN lines, as it should, but this test is about the speed map."""
    servers = []

    def start() -> str:
        channel = f"selftest-{time.monotonic_ns()}"
        backend = get_backend("stepfoc")
        model = backend.sim_model(load_profile("msg-150"), 0, None)
        settings = Settings("sim://msg-150", {"time_scale": MSG_SCALE}, {})
        servers.append(backend.serve([model], f"can://virtual/{channel}", settings))
        return f"stepfoc+can://virtual/{channel}?node=0"

    yield start
    for server in servers:
        server.close()


def _run(capsys, *argv: str) -> tuple[int, dict]:
    code = main(["selftest", *argv, "--yes", "--json", "--time-scale", MSG_SCALE])
    captured = capsys.readouterr()
    assert captured.out, (code, captured.err)
    doc = json.loads(captured.out)
    validate(doc)
    return code, doc


def test_msg_measured_profile_passes_and_an_off_map_warns(fresh_msg, capsys, tmp_path: Path) -> None:
    measured = tmp_path / "msg-150-bench.toml"
    code, first = _run(capsys, fresh_msg(), "--profile", "msg-150", "--write-profile", str(measured))
    assert code in (0, 3) and first["written_profile"] == str(measured)
    assert (code == 0) == first["ok"]
    written = load_file(measured)  # loads back through the profile loader, base resolved
    assert tomllib.loads(measured.read_text())["extends"] == "msg-150"
    assert written.maps.open_width_mm == 105.0  # inherited

    # The written profile makes every requested speed the speed the jaws move.
    code, second = _run(capsys, fresh_msg(), "--profile", str(measured))
    assert [ln["verdict"] for ln in _speed_lines(second)] == ["PASS"] * 3, [
        (ln["check"], ln["measured"], ln["expected"]) for ln in _speed_lines(first) + _speed_lines(second)
    ]
    assert code == 0 and second["ok"]

    # A map three times too fast: the jaws move at a third of what is asked; the selftest must notice.
    data = tomllib.loads(measured.read_text())
    off = tmp_path / "msg-150-off.toml"
    off.write_text(
        f'extends = "msg-150"\nname = "msg-150-off"\n[maps]\n'
        f"ticks_per_mm = {data['maps']['ticks_per_mm'] / 3}\n"
        "[mechanics]\nmin_speed_mm_s = 9.0\n"  # the slowest speed byte runs 3x faster too
    )
    code, third = _run(capsys, fresh_msg(), "--profile", str(off))
    assert code == 3 and not third["ok"]
    speeds = _speed_lines(third)
    assert speeds and all(ln["verdict"] == "WARN" for ln in speeds)
    assert all(0.2 < ln["value"] / float(ln["check"].split()[1]) < 0.5 for ln in speeds)


# --- the arithmetic ------------------------------------------------------------------------------------


def test_fit_recovers_a_slope_and_its_uncertainty_grows_with_noise() -> None:
    clean = [(t / 100, 20 + 50 * t / 100) for t in range(0, 101)]  # 50 mm/s from 20 to 70 mm
    speed, unc, used, method = fit_speed(clean, 20, 70, 1.0, 0.01)
    assert method == "fit" and abs(speed - 50) < 1e-9 and unc < 1e-6 and used > 50
    noisy = [(t, w + (0.8 if i % 2 else -0.8)) for i, (t, w) in enumerate(clean)]
    _, unc_noisy, _, _ = fit_speed(noisy, 20, 70, 1.0, 0.01)
    assert unc_noisy > unc


def test_too_few_samples_fall_back_to_the_duration_and_too_coarse_is_a_warn() -> None:
    speed, unc, _, method = fit_speed([(0.0, 20.0), (0.5, 70.0)], 20, 70, 0.5, 0.25)
    assert method == "duration" and speed == 100.0 and unc == math.inf
    line = speed_verdict(SpeedMeasurement(100.0, speed, unc, 2, method), 0.15)
    assert unc > MAX_UNCERTAINTY and line.verdict == "WARN" and "too coarse" in line.note


def test_refitted_map_makes_requests_come_true() -> None:
    # jaws move at 3x the request: both ends of the map scale by 3
    low, high = fitted_speed_map([20, 45, 70], [60, 135, 210], 1.0, 100.0)
    assert abs(low - 3.0) < 1e-9 and abs(high - 300.0) < 1e-9
    # one noisy point moves the factor a little, not the slow end to the middle of the map
    low, high = fitted_speed_map([20, 45, 70], [60, 135, 140], 1.0, 100.0)
    assert 2.0 < low < 3.0 and 200 < high < 300


def test_selftest_over_zenoh_runs_through_the_api(cli) -> None:
    pytest.importorskip("zenoh")
    import os
    import re
    import select
    import subprocess
    import sys

    proc = subprocess.Popen(
        [
            sys.executable,
            "-m",
            "grippers",
            "serve",
            f"sim://wsg50?time_scale={WSG_SCALE}",
            "--listen",
            "tcp/127.0.0.1:0",
        ],
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,
        text=True,
        env={**os.environ, "PYTHONUNBUFFERED": "1"},
    )
    try:
        assert proc.stdout is not None
        fd, seen, url, deadline = proc.stdout.fileno(), "", None, time.monotonic() + 30
        while url is None and time.monotonic() < deadline and proc.poll() is None:
            if select.select([fd], [], [], 0.2)[0]:
                seen += os.read(fd, 65536).decode()
                m = re.search(r"^\S+: .* serving at (\S+)$", seen, re.M)
                url = m.group(1) if m else None
        assert url, seen
        r = cli("selftest", url, "--time-scale", WSG_SCALE, "--yes", "--json", timeout=120)
        assert r.returncode in (0, 3), r.stderr  # finished; speeds over the network may be judged coarse
        doc = r.json()
        settings = [ln for ln in doc["lines"] if ln["check"] == "settings"]
        assert settings and "not served" in settings[0]["note"]
        assert any(ln["check"] == "close without a part" and ln["verdict"] == "PASS" for ln in doc["lines"])
    finally:
        proc.terminate()
        proc.communicate(timeout=15)


def test_on_a_terminal_it_asks_and_no_moves_nothing() -> None:
    import os
    import pty
    import subprocess
    import sys

    master, slave = pty.openpty()
    try:
        proc = subprocess.Popen(
            [sys.executable, "-m", "grippers", "selftest", f"sim://wsg50?time_scale={WSG_SCALE}"],
            stdin=slave,
            stdout=subprocess.PIPE,
            stderr=subprocess.PIPE,
            text=True,
            env={**os.environ, "PYTHONUNBUFFERED": "1"},
        )
        os.write(master, b"n\n")
        out, err = proc.communicate(timeout=60)
    finally:
        os.close(master)
        os.close(slave)
    assert proc.returncode == 2, err
    assert "keep the jaws EMPTY" in err and err.strip().splitlines()[-1].endswith(
        "not confirmed; nothing moved"
    )
    assert "go ahead? [y/N]" in out


def test_write_profile_refuses_a_base_its_name_does_not_find_before_moving(
    cli, sim_process, tmp_path
) -> None:
    url = sim_process("wsg", "--listen", "tcp://127.0.0.1:0").url
    base = tmp_path / "wsg50-glass.toml"
    base.write_text('extends = "wsg50"\nname = "wsg50-glass"\n[safety]\nmax_force_n = 15.0\n')
    r = cli(
        "selftest",
        url,
        "--profile",
        str(base),
        "--yes",
        "--write-profile",
        str(tmp_path / "out.toml"),
    )
    assert r.returncode == 2 and "GRIPPERS_PROFILE_PATH" in r.one_error_line()
    assert not (tmp_path / "out.toml").exists()
    assert cli("state", url, "--json").json()["state"]["referenced"] is False  # nothing moved
