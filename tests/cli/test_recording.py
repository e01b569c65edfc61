"""Issue 31 §3 and issue 33 §1/§3: several grippers in one recording, the Python recorder, files that a reader
can always read (rows written as they come, a second Ctrl-C, a full disk), plot of several grippers and files,
"not reported", and the --do mistakes that are usage errors."""

from __future__ import annotations

import contextlib
import io
import json
import os
import signal
import subprocess
import sys
import time
from pathlib import Path

import pytest

import grippers
from grippers.recording import RecordingError, load

WSG = "sim://wsg50?part_width_mm=40&time_scale=20"
MSG = "sim://msg-150?time_scale=20"
ENV = {**os.environ, "PYTHONUNBUFFERED": "1", "PYTHONDONTWRITEBYTECODE": "1"}


def _main(*argv: str) -> tuple[int, str, str]:
    from grippers.cli import main

    out, err = io.StringIO(), io.StringIO()
    with contextlib.redirect_stderr(err), contextlib.redirect_stdout(out):
        code = main(list(argv))
    return code, out.getvalue(), err.getvalue()


def _popen(*argv: str, **kw: object) -> subprocess.Popen:
    return subprocess.Popen(
        [sys.executable, "-m", "grippers", *argv],
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,
        text=True,
        env=ENV,
        **kw,  # type: ignore[arg-type]
    )


def _rows_of(path: Path) -> list[dict]:
    try:
        return load(path).rows
    except RecordingError:  # not created yet, or its header not yet written
        return []


def _wait_rows(proc: subprocess.Popen, path: Path, ready, bound: float = 300.0) -> list[dict]:
    """Poll the file being written until ``ready(rows)``: observable state, bounded for a broken run only."""
    deadline = time.monotonic() + bound
    while time.monotonic() < deadline:
        assert proc.poll() is None, proc.communicate()
        rows = _rows_of(path)
        if ready(rows):
            return rows
        time.sleep(0.05)
    raise AssertionError(f"{path}: not ready within {bound:g} s: {len(_rows_of(path))} rows")


def _states(rows: list[dict], gripper: str | None = None) -> list[dict]:
    return [r for r in rows if r["kind"] == "state" and (gripper is None or r["gripper"] == gripper)]


# --- several grippers, one file -----------------------------------------------------------------------------


@pytest.mark.parametrize("suffix", [".csv", ".jsonl", ".mcap"])
def test_two_grippers_record_into_one_file(cli, tmp_path: Path, suffix: str) -> None:
    if suffix == ".mcap":
        pytest.importorskip("mcap_ros2")
    out = tmp_path / f"both{suffix}"
    r = cli(
        "record", f"left={WSG}", f"right={MSG}", "-o", str(out), "--rate", "50",
        "--do", "home", "--do", "left: grasp 40 --force 20", "--json",
    )  # fmt: skip
    assert r.returncode == 0, r.stderr
    doc = r.json()
    assert [g["name"] for g in doc["grippers"]] == ["left", "right"]
    recording = load(out)
    assert recording.grippers == ["left", "right"] and recording.cut is None
    assert recording.header["grippers"] == [{"name": "left", "target": WSG}, {"name": "right", "target": MSG}]
    assert len(_states(recording.rows, "left")) >= 5 and len(_states(recording.rows, "right")) >= 5
    events = [(r["gripper"], r["command"], r["phase"]) for r in recording.rows if r["kind"] == "command"]
    assert sorted(events) == sorted(
        [
            ("left", "home", "start"),
            ("left", "home", "done"),
            ("right", "home", "start"),
            ("right", "home", "done"),
            ("left", "left: grasp 40 --force 20", "start"),
            ("left", "left: grasp 40 --force 20", "done"),
        ]
    )
    assert _states(recording.rows, "left")[-1]["width_mm"] == pytest.approx(40.0, abs=1.0)
    if suffix == ".csv":
        with open(out, newline="") as fh:
            assert fh.readline().strip().split(",")[:3] == ["t_s", "gripper", "kind"]
    if suffix == ".mcap":
        from mcap.reader import make_reader

        with open(out, "rb") as fh:
            summary = make_reader(fh).get_summary()
        assert summary is not None  # finished: a summary and a footer
        topics = {c.topic for c in summary.channels.values()}
        assert {"/left/joint_states", "/right/joint_states", "/grippers/record"} <= topics


def test_do_names_a_gripper_that_is_not_there(tmp_path: Path) -> None:
    code, _, err = _main("record", f"left={WSG}", "-o", str(tmp_path / "x.csv"), "--do", "right: home")
    assert code == 2 and "no gripper named 'right'" in err and not (tmp_path / "x.csv").exists()
    code, _, err = _main("record", f"a={WSG}", f"a={MSG}", "-o", str(tmp_path / "x.csv"))
    assert code == 2 and "given twice" in err


# --- the Python recorder ------------------------------------------------------------------------------------


def test_the_python_recorder_marks_commands_and_names_grippers(tmp_path: Path) -> None:
    out = tmp_path / "run.jsonl"
    with grippers.open(WSG) as left, grippers.open(MSG) as right:
        with grippers.record(out, {"left": left, "right": right}, rate_hz=50) as rec:
            with rec.command("home"):
                left.home()
                right.home()
            with pytest.raises(grippers.LimitError), rec.command("move -1", gripper="right"):
                right.move(-0.001)
            rows = _wait_rows_in_process(out, lambda rows: len(_states(rows, "right")) >= 3)
            assert rows  # a reader finds the rows while the recording runs
        assert rec.states >= 6 and rec.events == 4 and rec.files == [str(out)]
    recording = load(out)
    phases = [(r["gripper"], r["command"], r["phase"]) for r in recording.rows if r["kind"] == "command"]
    assert phases == [
        (None, "home", "start"),
        (None, "home", "done"),
        ("right", "move -1", "start"),
        ("right", "move -1", "failed"),
    ]
    assert "move" in [r for r in recording.rows if r.get("phase") == "failed"][0]["detail"]
    with grippers.open(WSG) as g:
        with pytest.raises(grippers.RecordingError, match="a letter"):
            grippers.record(tmp_path / "x.csv", {"left gripper": g})
        with pytest.raises(grippers.RecordingError, match="must end in"):
            grippers.record(tmp_path / "x.txt", g)
        with grippers.record(tmp_path / "one.csv", g) as rec:
            pass
    assert load(tmp_path / "one.csv").grippers == ["gripper"]


def _wait_rows_in_process(path: Path, ready, bound: float = 120.0) -> list[dict]:
    deadline = time.monotonic() + bound
    while time.monotonic() < deadline:
        rows = _rows_of(path)
        if ready(rows):
            return rows
        time.sleep(0.05)
    raise AssertionError(f"{path}: not ready within {bound:g} s")


CLOSE_UNDER_CTRL_C = """
import os, signal, sys, time
import grippers
from grippers import recording_mcap
from grippers.recording import load

real_finish = recording_mcap.McapSink.finish

def slow_finish(self):
    for _ in range(3):  # Ctrl-C three times while the summary is being written
        os.kill(os.getpid(), signal.SIGINT)
        time.sleep(0.05)
    real_finish(self)

recording_mcap.McapSink.finish = slow_finish
out = sys.argv[1]
with grippers.open(sys.argv[2]) as g:
    rec = grippers.record(out, g)
    while sum(1 for r in (load(out).rows if os.path.getsize(out) > 200 else []) if r["kind"] == "state") < 3:
        time.sleep(0.05)
    try:
        rec.close()
    except KeyboardInterrupt:
        print("interrupted after the file was finished")
"""


def test_ctrl_c_while_the_recorder_closes_still_finishes_the_file(tmp_path: Path) -> None:
    """Ctrl-C (three of them) while the MCAP's summary is being written: close() waits for the writer and
    raises the interrupt after it; the file is whole (it was 233 unreadable bytes, issue 33 §1)."""
    pytest.importorskip("mcap_ros2")
    out = tmp_path / "run.mcap"
    proc = subprocess.run(
        [sys.executable, "-c", CLOSE_UNDER_CTRL_C, str(out), WSG],
        capture_output=True, text=True, timeout=300, env=ENV,
    )  # fmt: skip
    assert proc.stdout.strip() == "interrupted after the file was finished", proc.stderr
    recording = load(out)
    assert recording.cut is None and len(_states(recording.rows)) >= 3


# --- files a reader can always read -------------------------------------------------------------------------


@pytest.mark.parametrize("suffix", [".jsonl", ".mcap"])
def test_second_ctrl_c_while_record_writes_leaves_a_readable_file(tmp_path: Path, suffix: str) -> None:
    if suffix == ".mcap":
        pytest.importorskip("mcap_ros2")
    out = tmp_path / f"run{suffix}"
    proc = _popen("record", WSG, "-o", str(out), "--rate", "200", "--duration", "3600")
    try:
        _wait_rows(proc, out, lambda rows: len(_states(rows)) >= 20)
        for _ in range(3):  # Ctrl-C, then again while it ends
            proc.send_signal(signal.SIGINT)
            time.sleep(0.01)
        _, err = proc.communicate(timeout=60)
    finally:
        proc.kill()
        proc.communicate()
    assert proc.returncode == 130, err
    recording = load(out)
    assert recording.cut is None and len(_states(recording.rows)) >= 20


@pytest.mark.parametrize("suffix", [".csv", ".jsonl", ".mcap"])
def test_a_file_size_limit_names_the_file_and_keeps_what_was_written(tmp_path: Path, suffix: str) -> None:
    """RLIMIT_FSIZE with SIGXFSZ ignored: writes fail with EFBIG, as on a full disk."""
    if suffix == ".mcap":
        pytest.importorskip("mcap_ros2")
    import resource

    limit = 48 * 1024

    def limited() -> None:
        signal.signal(signal.SIGXFSZ, signal.SIG_IGN)
        resource.setrlimit(resource.RLIMIT_FSIZE, (limit, limit))

    out = tmp_path / f"big{suffix}"
    proc = _popen("record", WSG, "-o", str(out), "--rate", "200", "--duration", "3600", preexec_fn=limited)
    try:
        said, err = proc.communicate(timeout=300)
    finally:
        proc.kill()
        proc.communicate()
    lines = [line for line in err.splitlines() if line.strip()]
    assert proc.returncode == 1, err
    assert lines == [f"grippers record: error: {out}: cannot write: File too large"]
    recording = load(out)  # what was written before the limit reads, as far as it is complete
    assert len(_states(recording.rows)) >= 20
    # Issue 43 §9: the summary counts the rows in the file, not the samples taken ("recorded 450 states"
    # with 231 in the file before).
    events = sum(1 for r in recording.rows if r["kind"] == "command")
    assert f"recorded {len(_states(recording.rows))} states and {events} command events" in said, said


@pytest.mark.parametrize("suffix", [".csv", ".jsonl", ".mcap"])
def test_plot_draws_the_complete_part_of_a_file_cut_short(cli, tmp_path: Path, suffix: str) -> None:
    pytest.importorskip("matplotlib")
    if suffix == ".mcap":
        pytest.importorskip("mcap_ros2")
    out = tmp_path / f"run{suffix}"
    with grippers.open(WSG) as g, grippers.record(out, g, rate_hz=100) as rec:
        with rec.command("home"):
            g.home()
        # MCAP: a chunk at least every 0.5 s; two seconds give a few, and the cut lands after the first
        _wait_rows_in_process(out, lambda rows: len(_states(rows)) >= 200)
    whole = len(_states(load(out).rows))
    data = out.read_bytes()
    cut = len(data) * 2 // 3 + 7  # in the middle of a row (or a record)
    if suffix != ".mcap" and data[cut - 1 : cut] == b"\n":
        cut += 1  # not just after a newline, where a text file would look whole (one time in a row's length)
    out.write_bytes(data[:cut])
    recording = load(out)
    assert recording.cut is not None and 0 < len(_states(recording.rows)) < whole
    r = cli("plot", str(out), "-o", str(tmp_path / "run.png"), "--json")
    assert r.returncode == 0, r.stderr
    assert "cut short" in r.stderr and str(out) in r.stderr
    assert r.json()["recordings"][0]["cut"] == recording.cut


# --- plot: several grippers, several files, "not reported" --------------------------------------------------


def test_plot_says_not_reported_instead_of_an_empty_panel(cli, tmp_path: Path) -> None:
    pytest.importorskip("matplotlib")
    out = tmp_path / "msg.jsonl"
    with grippers.open(MSG) as g, grippers.record(out, g) as rec, rec.command("home"):
        g.home()
    assert all(r["speed_mm_s"] is None for r in _states(load(out).rows))  # the MSG reports no speed
    svg = tmp_path / "msg.svg"
    assert cli("plot", str(out), "-o", str(svg)).returncode == 0
    assert svg.read_text().count(">not reported<") == 1  # the speed panel; current is reported


def test_plot_of_two_grippers_and_two_files_on_one_time_axis(cli, tmp_path: Path) -> None:
    pytest.importorskip("matplotlib")
    both, later = tmp_path / "both.csv", tmp_path / "later.jsonl"
    with grippers.open(WSG) as left, grippers.open(MSG) as right:
        with grippers.record(both, {"left": left, "right": right}) as rec, rec.command("home"):
            left.home()
            right.home()
        with grippers.record(later, left):
            _wait_rows_in_process(later, lambda rows: len(_states(rows)) >= 3)
    svg = tmp_path / "all.svg"
    r = cli("plot", str(both), str(later), "-o", str(svg), "--json")
    assert r.returncode == 0, r.stderr
    doc = r.json()
    assert [(d["recording"], d["grippers"]) for d in doc["recordings"]] == [
        (str(both), ["left", "right"]),
        (str(later), ["gripper"]),
    ]
    text = svg.read_text()
    for label in ("both.csv: left", "both.csv: right", "later.jsonl"):
        assert label in text  # the legend
    assert "not reported: both.csv: right" in text  # the MSG's speed, beside the WSG's
    from grippers.cli.plot import collect

    series, _ = collect([load(both), load(later)])
    assert min(x for x in series[2].xy("width_mm")[0]) > max(x for x in series[0].xy("width_mm")[0])


# --- --do mistakes are usage errors (issue 33 §3) -----------------------------------------------------------


@pytest.mark.parametrize(
    ("do", "says"),
    [
        ("wait 1e308", "at most 86400 s"),
        ("move 50 'x", "no closing quotation"),
        ("move", "the following arguments are required: WIDTH_MM"),
        ("grasp 40 --motion-timeout 1e300", "at most 86400 s"),
        ("left: wait 1", "not for one gripper"),
    ],
)
def test_do_mistakes_are_readable_usage_errors(tmp_path: Path, do: str, says: str) -> None:
    code, _, err = _main("record", f"left={WSG}", "-o", str(tmp_path / "x.csv"), "--do", do)
    lines = err.strip().splitlines()
    assert code == 2 and len(lines) == 1 and says in lines[0] and f"--do {do!r}" in lines[0], err
    assert "Traceback" not in err and not (tmp_path / "x.csv").exists()


# --- an interrupt stops what --do started -------------------------------------------------------------------


def test_ctrl_c_stops_the_motions_record_started_on_every_gripper(cli, sim_process, tmp_path: Path) -> None:
    """Two grippers moving at once (each call in a thread of its own, nothing waits in the main thread):
    Ctrl-C must stop both before record exits. Simulators in their own processes, at real time, so the
    state after exit shows whether the motion went on (50 mm or more at 5 mm/s: 10 s or more): the WSG opens
    to 110 mm on homing, the MSG closes to 0, and both are sent to 60 mm."""
    urls = [
        sim_process("wsg", "--listen", "tcp://127.0.0.1:0").url,
        # An MSG on its UART: it runs a motion to its end whatever the host does (the WSG's simulator stops
        # when its connection closes), so only a stop sent before exit leaves it still.
        sim_process("msg", "--listen", "pty", "--profile", "msg-150").url + "?profile=msg-150",
    ]
    out = tmp_path / "run.jsonl"
    proc = _popen("record", f"a={urls[0]}", f"b={urls[1]}", "-o", str(out), "--do", "home",
                  "--do", "move 60 --speed 5")  # fmt: skip

    def both_moving(rows: list[dict]) -> bool:
        started = {r["gripper"]: r["t_s"] for r in rows if r.get("command") == "move 60 --speed 5"}
        return all(
            any(s["t_s"] > started[g] and s["moving"] for s in _states(rows, g)) if g in started else False
            for g in ("a", "b")
        )

    try:
        _wait_rows(proc, out, both_moving)
        proc.send_signal(signal.SIGINT)
        _, err = proc.communicate(timeout=60)
    finally:
        proc.kill()
        proc.communicate()
    assert proc.returncode == 130, err
    for url in urls:
        state = cli("state", url, "--json").json()["state"]
        assert state["moving"] is False and abs(state["width_mm"] - 60.0) > 5.0, state
    failed = [r for r in load(out).rows if r.get("phase") == "failed"]
    assert {r["gripper"] for r in failed} == {"a", "b"}  # stamped as stopped, not as done


def test_readme_recorder_example_is_in_the_readme() -> None:
    text = (Path(__file__).resolve().parents[2] / "README.md").read_text()
    assert "grippers.record(" in text


def test_record_result_schema_lists_the_grippers() -> None:
    from grippers.cli.schemas import validate

    validate(
        json.loads(
            '{"schema": "grippers.record-result/1", "target": "a b",'
            ' "grippers": [{"name": "a", "target": "a"}],'
            ' "output": "x.csv", "format": "csv", "files": ["x.csv"], "states": 1, "command_events": 0,'
            ' "failed": null}'
        )
    )


def test_a_program_that_ends_without_closing_leaves_a_finished_file(tmp_path: Path) -> None:
    """The writer thread finishes the file when the main thread has ended (a program without close() or
    with); it used to wait on its queue, fed by the stream, and the program never exited."""
    pytest.importorskip("mcap_ros2")
    out = tmp_path / "forgot.mcap"
    script = (
        "import sys, grippers\n"
        "g = grippers.open(sys.argv[2])\n"
        "rec = grippers.record(sys.argv[1], g)\n"
        "for _ in range(3): g.state()\n"
    )
    proc = subprocess.run(
        [sys.executable, "-c", script, str(out), WSG], capture_output=True, text=True, timeout=120, env=ENV
    )
    assert proc.returncode == 0, proc.stderr
    assert load(out).cut is None
