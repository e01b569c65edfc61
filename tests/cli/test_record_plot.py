"""Issue 16 §3: `grippers record` writes states and the commands it ran, with times, in CSV and JSON Lines;
`grippers plot` draws them. The picture test checks the file is an image of the expected size that shows
curves (many pixels of the curves' colour), not a blank canvas."""

from __future__ import annotations

import json
from pathlib import Path

import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from grippers.recording import read

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
    """Ctrl-C once a state is in the file (observable state: rows are written as they come), never after a
    fixed time or a log line: it used to wait for "first state sampled" on stderr with select() on a text
    pipe whose buffer could already hold that line, and failed a busy run with "no state sampled"."""
    import os
    import signal
    import subprocess
    import sys

    from grippers.recording import load

    out = tmp_path / "cut.jsonl"
    proc = subprocess.Popen(
        [sys.executable, "-m", "grippers", "record", URL, "-o", str(out), "--duration", "3600"],
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,
        text=True,
        env={**os.environ, "PYTHONUNBUFFERED": "1"},
    )
    try:
        wait_for_states(proc, out)
        proc.send_signal(signal.SIGINT)
        _, err = proc.communicate(timeout=60)
    finally:
        proc.kill()
        proc.communicate()
    assert proc.returncode == 130 and err.strip().splitlines()[-1] == "grippers record: interrupted"
    recording = load(out)
    assert recording.cut is None and recording.rows and all(r["kind"] == "state" for r in recording.rows)


def wait_for_states(proc, path: Path, count: int = 1, until=None, bound: float = 300.0) -> list:
    """Poll the file the recorder is writing until it holds ``count`` states (and ``until(rows)``, if
    given): a bound for a broken run only, never a measure of speed."""
    import time

    from grippers.recording import RecordingError, load

    deadline = time.monotonic() + bound
    while time.monotonic() < deadline:
        assert proc.poll() is None, proc.communicate()
        try:
            rows = load(path).rows
        except RecordingError:  # not created yet, or the header not yet written
            rows = []
        if sum(1 for r in rows if r["kind"] == "state") >= count and (until is None or until(rows)):
            return rows
        time.sleep(0.05)
    raise AssertionError(f"{path}: no {count} states within {bound:g} s")


def test_record_ctrl_c_before_the_gripper_opened_leaves_no_empty_file(tmp_path: Path) -> None:
    """A Ctrl-C (or any failure) while the gripper is being opened: nothing was recorded, and the file the
    sink created at start (to find a bad path early) is removed rather than left empty (it read as "not a
    grippers recording" later)."""
    from grippers.recording import open_sink, temporary_of

    for name in ("a.jsonl", "b.csv"):
        sink = open_sink(tmp_path / name)
        assert temporary_of(tmp_path / name).exists()  # under a temporary name until it starts (issue 43 §2)
        sink.abandon()
    assert list(tmp_path.iterdir()) == []


# --- issue 22 §2 and §4, issue 23 §3, issue 21 §4 -------------------------------------------------------


def test_csv_starts_with_its_columns_for_plain_readers(cli, tmp_path: Path) -> None:
    import csv

    from grippers.recording import COLUMNS, RECORD_SCHEMA_ID

    out = tmp_path / "grasp.csv"
    assert cli("record", URL, "-o", str(out), "--do", "home").returncode == 0
    with open(out, newline="") as fh:
        rows = list(csv.DictReader(fh))
    assert tuple(rows[0].keys()) == COLUMNS and rows[0]["kind"] in ("state", "command")
    float(rows[0]["t_s"])
    side = json.loads((tmp_path / "grasp.csv.json").read_text())
    assert side["schema"] == RECORD_SCHEMA_ID and side["target"] == URL
    pandas = pytest.importorskip("pandas")
    frame = pandas.read_csv(out)
    assert tuple(frame.columns) == COLUMNS and len(frame) == len(rows)


def test_old_csv_with_a_comment_header_still_reads(tmp_path: Path) -> None:
    old = tmp_path / "old.csv"
    old.write_text(
        '# {"schema": "grippers.record/1", "target": "sim://wsg50"}\n'
        "t_s,kind,width_mm,speed_mm_s,force_n,current_a,grasp_state,moving,referenced,faults,command,phase,detail\n"
        "0.0,state,10.0,0.0,0.0,,idle,False,True,,,,\n"
    )
    header, rows = read(old)
    assert header["target"] == "sim://wsg50" and rows[0]["width_mm"] == 10.0


def test_plot_json_says_what_was_drawn(cli, tmp_path: Path) -> None:
    rec = tmp_path / "r.jsonl"
    assert cli("record", URL, "-o", str(rec), "--do", "home").returncode == 0
    r = cli("plot", str(rec), "-o", str(tmp_path / "r.svg"), "--json")
    assert r.returncode == 0, r.stderr
    doc = r.json()  # validated against the CLI's schemas by the fixture
    assert doc["schema"] == "grippers.plot/1" and doc["output"] == str(tmp_path / "r.svg")
    assert doc["states"] > 0 and doc["commands"] == 2


def test_record_json_is_json(cli, tmp_path: Path) -> None:
    out = tmp_path / "r.jsonl"
    r = cli("record", URL, "-o", str(out), "--do", "home", "--json")
    assert r.returncode == 0, r.stderr
    doc = r.json()
    assert doc["schema"] == "grippers.record-result/1" and doc["files"] == [str(out)]
    assert doc["states"] > 0 and doc["command_events"] == 2 and doc["failed"] is None


def test_record_bad_path_fails_before_the_gripper_moves(cli, sim_process, tmp_path: Path) -> None:
    url = sim_process("wsg", "--listen", "tcp://127.0.0.1:0").url
    r = cli("record", url, "-o", str(tmp_path / "missing-dir" / "run.csv"), "--do", "home")
    assert r.returncode == 2 and "cannot write" in r.one_error_line()
    state = cli("state", url, "--json").json()
    assert state["state"]["referenced"] is False  # home never ran


def test_mcap_opens_in_an_independent_reader(cli, tmp_path: Path) -> None:
    pytest.importorskip("mcap_ros2")
    rosbags_reader = pytest.importorskip("rosbags.rosbag2")
    from rosbags.typesys import Stores, get_typestore

    from grippers.recording_mcap import JOINT_STATE_DEFINITION

    out = tmp_path / "run.mcap"
    r = cli("record", URL, "-o", str(out), "--rate", "100", "--do", "home", "--do", "grasp 40 --force 20")
    assert r.returncode == 0, r.stderr
    store = get_typestore(Stores.ROS2_JAZZY)
    with rosbags_reader.Reader(out) as bag:
        topics = {c.topic: c for c in bag.connections}
        assert topics["/joint_states"].msgtype == "sensor_msgs/msg/JointState"
        assert topics["/joint_states"].msgdef.data == JOINT_STATE_DEFINITION
        assert "/grippers/record" in topics  # the JSON channel does not stop a ROS reader
        states = [
            store.deserialize_cdr(raw, "sensor_msgs/msg/JointState")
            for conn, _, raw in bag.messages()
            if conn.topic == "/joint_states"
        ]
    assert len(states) >= 10 and list(states[-1].name) == ["gripper_joint"]
    assert states[-1].position[0] == pytest.approx(0.040, abs=0.001)  # metres
    assert states[-1].effort[0] == pytest.approx(20.0)
    header, rows = read(out)  # and grippers reads its own JSON channel back
    assert header["target"] == URL and sum(1 for row in rows if row["kind"] == "state") == len(states)
    png = tmp_path / "run.png"
    assert cli("plot", str(out), "-o", str(png)).returncode == 0 and png.stat().st_size > 0


def test_simultaneous_commands_share_one_label(cli, tmp_path: Path) -> None:
    from grippers.cli.plot import label_groups

    assert label_groups([(0.5, "move 30"), (0.5, "stop"), (2.0, "home")], 10.0) == [
        (0.5, "move 30 / stop"),
        (2.0, "home"),
    ]
    rec = tmp_path / "two.jsonl"
    lines = [{"schema": "grippers.record/1", "target": "t"}]
    lines += [{"t_s": i / 10, "kind": "state", "width_mm": 50.0 + i} for i in range(20)]
    lines += [
        {"t_s": 0.5, "kind": "command", "command": "move 30", "phase": "start"},
        {"t_s": 0.5, "kind": "command", "command": "stop", "phase": "start"},
    ]
    rec.write_text("".join(json.dumps(line) + "\n" for line in lines))
    svg = tmp_path / "two.svg"
    assert cli("plot", str(rec), "-o", str(svg)).returncode == 0
    text = svg.read_text()
    assert text.count("move 30 / stop") == 1 and ">stop<" not in text and ">move 30<" not in text


def _plot_exit(path: Path) -> tuple[int, str]:
    import contextlib
    import io

    from grippers.cli import main

    err = io.StringIO()
    with contextlib.redirect_stderr(err), contextlib.redirect_stdout(io.StringIO()):
        code = main(["plot", str(path), "-o", str(path.with_suffix(".png"))])
    return code, err.getvalue()


_json_values = st.recursive(
    st.none() | st.booleans() | st.integers() | st.floats() | st.text(max_size=8),
    lambda inner: st.lists(inner, max_size=3) | st.dictionaries(st.text(max_size=6), inner, max_size=3),
    max_leaves=8,
)
_rows = st.fixed_dictionaries(
    {"t_s": _json_values, "kind": st.sampled_from(["state", "command", "other"]) | _json_values},
    optional={
        "width_mm": _json_values,
        "force_n": _json_values,
        "command": _json_values,
        "phase": _json_values,
    },
)


@settings(max_examples=40, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(
    rows=st.lists(_rows | _json_values, max_size=5),
    garbage=st.binary(max_size=64),
    suffix=st.sampled_from([".jsonl", ".csv", ".mcap"]),
)
def test_plot_of_any_malformed_recording_is_one_line_and_exit_2(rows, garbage, suffix) -> None:
    import tempfile

    with tempfile.TemporaryDirectory() as d:
        path = Path(d) / f"fuzz{suffix}"
        if suffix == ".jsonl":
            head = json.dumps({"schema": "grippers.record/1"}) + "\n"
            path.write_text(head + "".join(json.dumps(r) + "\n" for r in rows) + garbage.decode("latin-1"))
        elif suffix == ".csv":
            path.write_bytes(b"t_s,kind,width_mm\n" + garbage)
        else:
            path.write_bytes(b"\x89MCAP0\r\n" + garbage)
        code, err = _plot_exit(path)
    assert code in (0, 2), err
    if code == 2:
        lines = [line for line in err.splitlines() if line.strip()]
        assert len(lines) == 1 and lines[0].startswith("grippers plot: error:") and "Traceback" not in err
