"""Issue 43 §2: a recording is never destroyed by a failed run (§9's count after a full disk is checked by
tests/cli/test_recording.py's file-size-limit test).

``grippers record wsg+tcp://127.0.0.1:1 -o run.csv`` deleted an existing ``run.csv`` and its ``run.csv.json``
when the gripper could not be opened (also ``.jsonl``, ``.mcap``, an unknown profile). The recording is now
written under a temporary name beside the final one and moved into place when it starts
(grippers/recording.py ``Sink``).
"""

from __future__ import annotations

import contextlib
import io
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
