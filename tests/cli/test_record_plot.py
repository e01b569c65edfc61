"""Issue 16 §3: `grippers record` writes states and the commands it ran, with times, in CSV and JSON Lines;
`grippers plot` draws them. The picture test checks the file is an image of the expected size that shows
curves (many pixels of the curves' colour), not a blank canvas."""

from __future__ import annotations

import json
from pathlib import Path

import pytest

from grippers.cli.recording import read

pytest.importorskip("matplotlib")

URL = "sim://wsg50?part_width_mm=40&time_scale=20"


@pytest.mark.parametrize("suffix", [".csv", ".jsonl"])
def test_record_states_and_commands(cli, tmp_path: Path, suffix: str) -> None:
    out = tmp_path / f"grasp{suffix}"
    r = cli("record", URL, "-o", str(out), "--rate", "100", "--do", "home", "--do", "grasp 40 --force 20")
    assert r.returncode == 0, r.stderr
    header, rows = read(out)
    assert header["target"] == URL and header["do"] == ["home", "grasp 40 --force 20"]
    events = [(row["command"], row["phase"]) for row in rows if row["kind"] == "command"]
    assert events == [
        ("home", "start"),
        ("home", "done"),
        ("grasp 40 --force 20", "start"),
        ("grasp 40 --force 20", "done"),
    ]
    states = [row for row in rows if row["kind"] == "state"]
    assert len(states) >= 10
    times = [row["t_s"] for row in rows]
    assert times == sorted(times)
    assert states[-1]["width_mm"] == pytest.approx(40.0, abs=1.0) and states[-1]["force_n"] == 20.0
    assert "grasped=True" in [row for row in rows if row.get("phase") == "done"][-1]["detail"]


def test_record_keeps_what_it_has_when_a_command_fails(cli, tmp_path: Path) -> None:
    out = tmp_path / "fail.jsonl"
    r = cli("record", URL, "-o", str(out), "--do", "move 30")  # not referenced: the device refuses
    assert r.returncode == 1 and "record" in r.one_error_line()
    _, rows = read(out)
    assert [row["phase"] for row in rows if row["kind"] == "command"] == ["start", "failed"]


def test_record_bad_do_is_a_usage_error_before_anything_moves(cli, tmp_path: Path) -> None:
    r = cli("record", URL, "-o", str(tmp_path / "x.csv"), "--do", "grasp forty")
    assert r.returncode == 2 and "--do 'grasp forty'" in r.one_error_line()
    assert not (tmp_path / "x.csv").exists()
    assert cli("record", URL, "-o", str(tmp_path / "x.txt")).returncode == 2


def _curve_pixels(png: Path) -> tuple[tuple[int, ...], int]:
    import matplotlib.image as mpimg
    import numpy as np

    img = mpimg.imread(png)
    rgb = (img[..., :3] * 255).astype(int)
    blue = np.array([31, 119, 180])  # matplotlib's tab:blue, the curves' colour
    return img.shape, int((np.abs(rgb - blue).sum(axis=-1) < 60).sum())


def test_plot_draws_the_curves(cli, tmp_path: Path) -> None:
    rec = tmp_path / "grasp.csv"
    assert cli("record", URL, "-o", str(rec), "--do", "home", "--do", "grasp 40 --force 20").returncode == 0
    png = tmp_path / "grasp.png"
    r = cli("plot", str(rec), "-o", str(png))
    assert r.returncode == 0, r.stderr
    shape, blue = _curve_pixels(png)
    assert shape[:2] == (700, 1000)
    assert blue > 1500  # three curves across the width of the picture; a blank or axes-only one has none
    svg = tmp_path / "grasp.svg"
    assert cli("plot", str(rec), "-o", str(svg)).returncode == 0
    text = svg.read_text()
    assert text.count("<path") > 20 and "#1f77b4" in text  # the curves' colour


def test_plot_refuses_what_is_not_a_recording(cli, tmp_path: Path) -> None:
    bad = tmp_path / "bad.jsonl"
    bad.write_text(json.dumps({"hello": 1}) + "\n")
    r = cli("plot", str(bad), "-o", str(tmp_path / "x.png"))
    assert r.returncode == 2 and "not a grippers recording" in r.one_error_line()


def test_record_ctrl_c_keeps_the_file_and_exits_130(tmp_path: Path) -> None:
    import os
    import signal
    import subprocess
    import sys
    import time

    out = tmp_path / "cut.jsonl"
    proc = subprocess.Popen(
        [sys.executable, "-m", "grippers", "record", URL, "-o", str(out), "--duration", "60"],
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,
        text=True,
        env={**os.environ, "PYTHONUNBUFFERED": "1"},
    )
    time.sleep(3.0)  # started and sampling (the exact moment does not matter)
    proc.send_signal(signal.SIGINT)
    _, err = proc.communicate(timeout=20)
    assert proc.returncode == 130 and err.strip().splitlines()[-1] == "grippers record: interrupted"
    _, rows = read(out)
    assert rows and all(row["kind"] == "state" for row in rows)
