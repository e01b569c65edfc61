"""Issue 43 §2 and §9: a recording is never destroyed by a failed run, and a run cut short by a full disk
says how many rows the file holds.

``grippers record wsg+tcp://127.0.0.1:1 -o run.csv`` deleted an existing ``run.csv`` and its ``run.csv.json``
when the gripper could not be opened (also ``.jsonl``, ``.mcap``, an unknown profile). The recording is now
written under a temporary name beside the final one and moved into place when it starts
(grippers/recording.py ``Sink``).
"""

from __future__ import annotations

import contextlib
import io
import json
import os
import signal
import subprocess
import sys
from pathlib import Path

import pytest

from grippers.recording import load, sidecar_of

ROOT = Path(__file__).resolve().parents[2]
WSG = "sim://wsg50?time_scale=20"


def _main(*argv: str) -> tuple[int, str, str]:
    from grippers.cli import main

    out, err = io.StringIO(), io.StringIO()
    with contextlib.redirect_stderr(err), contextlib.redirect_stdout(out):
        code = main(list(argv))
    return code, out.getvalue(), err.getvalue()


def _unopenable() -> str:
    import socket

    with socket.socket() as s:  # a port nobody listens on: the connection is refused at once
        s.bind(("127.0.0.1", 0))
        port = s.getsockname()[1]
    return f"wsg+tcp://127.0.0.1:{port}"


@pytest.mark.parametrize("suffix", [".csv", ".jsonl", ".mcap"])
@pytest.mark.parametrize("how", ["unopenable", "unknown-profile"])
def test_a_failed_run_leaves_the_users_files_as_they_were(tmp_path: Path, suffix: str, how: str) -> None:
    if suffix == ".mcap":
        pytest.importorskip("mcap_ros2")
    out = tmp_path / f"run{suffix}"
    code, _, err = _main("record", WSG, "-o", str(out), "--duration", "0.3")
    assert code == 0, err
    before = {p.name: p.read_bytes() for p in tmp_path.iterdir()}
    assert out.name in before and (suffix != ".csv" or sidecar_of(out).name in before)
    target = _unopenable() if how == "unopenable" else "sim://no-such-profile"
    code, _, err = _main("record", target, "-o", str(out), "--duration", "0.3")
    assert code in (1, 2), err
    after = {p.name: p.read_bytes() for p in tmp_path.iterdir()}
    assert after == before  # every byte the user had, and no temporary file left behind


def test_a_run_that_starts_replaces_the_file(tmp_path: Path) -> None:
    out = tmp_path / "run.csv"
    out.write_text("old\n")
    sidecar_of(out).write_text("{}\n")
    code, _, err = _main("record", WSG, "-o", str(out), "--do", "home")
    assert code == 0, err
    recording = load(out)
    assert [r["phase"] for r in recording.rows if r["kind"] == "command"] == ["start", "done"]
    assert sorted(p.name for p in tmp_path.iterdir()) == ["run.csv", "run.csv.json"]


@pytest.mark.parametrize("suffix", [".csv", ".jsonl", ".mcap"])
def test_a_run_cut_short_by_a_full_disk_counts_the_rows_in_the_file(tmp_path: Path, suffix: str) -> None:
    """RLIMIT_FSIZE with SIGXFSZ ignored: writes fail with EFBIG, as on a full disk. Before, the summary
    counted every sample taken ("recorded 450 states" with 231 in the file)."""
    if suffix == ".mcap":
        pytest.importorskip("mcap_ros2")
    import resource

    limit = 48 * 1024

    def limited() -> None:
        signal.signal(signal.SIGXFSZ, signal.SIG_IGN)
        resource.setrlimit(resource.RLIMIT_FSIZE, (limit, limit))

    out = tmp_path / f"big{suffix}"
    proc = subprocess.Popen(
        [sys.executable, "-m", "grippers", "record", WSG, "-o", str(out), "--rate", "200"]
        + ["--duration", "3600", "--json"],
        cwd=ROOT,
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,
        text=True,
        env={**os.environ, "PYTHONUNBUFFERED": "1"},
        preexec_fn=limited,
    )
    try:
        stdout, err = proc.communicate(timeout=300)
    finally:
        proc.kill()
        proc.communicate()
    assert proc.returncode == 1, err
    doc = json.loads(stdout)
    rows = load(out).rows
    assert doc["states"] == sum(1 for r in rows if r["kind"] == "state") > 0, doc
    assert doc["command_events"] == sum(1 for r in rows if r["kind"] == "command")
