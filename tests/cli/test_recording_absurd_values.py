"""Issue 43 §6: a recording with a 5001-digit integer or a time of 1e308 is a one-line error naming the file
and the line (exit 2), not a ValueError from Python's integer limit or matplotlib's "Singular matrix"."""

from __future__ import annotations

import json
import subprocess
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[2]
HEAD = {"schema": "grippers.record/2", "grippers": [{"name": "gripper", "target": "x"}], "start_unix": 0}
GOOD = '{"t_s": 0, "gripper": "gripper", "kind": "state", "width_mm": 10}'


@pytest.mark.parametrize(
    ("row", "said"),
    [
        ('{"t_s": 0.2, "gripper": "gripper", "kind": "state", "width_mm": ' + "9" * 5001 + "}", "line 3"),
        ('{"t_s": ' + "1" * 5001 + ', "gripper": "gripper", "kind": "state"}', "line 3"),
        ('{"t_s": 1e308, "gripper": "gripper", "kind": "state", "width_mm": 5}', "line 3: t_s"),
        ('{"t_s": 0.3, "gripper": "gripper", "kind": "state", "force_n": -1e300}', "line 3: force_n"),
    ],
    ids=["long-int-width", "long-int-time", "time-1e308", "force-1e300"],
)
def test_plot_of_absurd_values_is_one_line_and_exit_2(tmp_path: Path, row: str, said: str) -> None:
    pytest.importorskip("matplotlib")
    path = tmp_path / "odd.jsonl"
    path.write_text(json.dumps(HEAD) + "\n" + GOOD + "\n" + row + "\n")
    r = subprocess.run(
        [sys.executable, "-m", "grippers", "plot", str(path), "-o", str(tmp_path / "odd.png")],
        cwd=ROOT,
        capture_output=True,
        text=True,
        timeout=120,
    )
    lines = [line for line in r.stderr.splitlines() if line.strip()]
    assert r.returncode == 2, r.stderr
    assert len(lines) == 1 and str(path) in lines[0] and said in lines[0], r.stderr


def test_a_csv_cell_of_5001_digits_names_its_line(tmp_path: Path) -> None:
    from grippers.recording import COLUMNS, RecordingError, load, sidecar_of

    path = tmp_path / "odd.csv"
    sidecar_of(path).write_text(json.dumps({**HEAD, "columns": list(COLUMNS)}) + "\n")
    cells = {c: "" for c in COLUMNS} | {
        "t_s": "0",
        "gripper": "gripper",
        "kind": "state",
        "width_mm": "9" * 5001,
    }
    path.write_text(",".join(COLUMNS) + "\n" + ",".join(cells[c] for c in COLUMNS) + "\n")
    with pytest.raises(RecordingError, match=r"odd.csv: line 2: width_mm"):
        load(path)
