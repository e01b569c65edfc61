"""Issue 43 §6: a profile file that replaces a built-in name (a ``wsg50.toml`` with 800 N where the built-in
says 80 N) is announced by ``profiles list``, ``doctor`` and ``info`` (grippers/cli/profile_notes.py)."""

from __future__ import annotations

import json
import os
import subprocess
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parents[2]


def _run(tmp_path: Path, *argv: str) -> subprocess.CompletedProcess[str]:
    env = {**os.environ, "GRIPPERS_PROFILE_PATH": str(tmp_path)}
    return subprocess.run(
        [sys.executable, "-m", "grippers", *argv],
        cwd=ROOT,
        capture_output=True,
        text=True,
        timeout=120,
        env=env,
    )


def test_a_file_replacing_a_built_in_profile_is_announced(tmp_path: Path) -> None:
    (tmp_path / "strong.toml").write_text('name = "wsg50"\nextends = "wsg50"\n[safety]\nmax_force_n = 79\n')
    listed = _run(tmp_path, "profiles", "list")
    assert listed.returncode == 0, listed.stderr
    said = f"{tmp_path / 'strong.toml'} replaces the built-in profile wsg50"
    assert said in listed.stderr, listed.stderr
    doctor = _run(tmp_path, "doctor")
    line = next((x for x in doctor.stdout.splitlines() if said in x), None)
    assert line is not None and line.startswith("WARN"), doctor.stdout


def test_info_on_a_gripper_whose_profile_replaces_a_built_in_says_so(tmp_path: Path) -> None:
    (tmp_path / "strong.toml").write_text('name = "wsg50"\nextends = "wsg50"\n[safety]\nmax_force_n = 79\n')
    said = f"{tmp_path / 'strong.toml'} replaces the built-in profile wsg50"
    shown = _run(tmp_path, "info", "sim://wsg50")
    assert shown.returncode == 0, shown.stderr
    assert f"warning: {said}" in shown.stdout, shown.stdout
    as_json = _run(tmp_path, "info", "sim://wsg50", "--json")
    assert any(said in w for w in json.loads(as_json.stdout)["warnings"]), as_json.stdout
    plain = _run(tmp_path, "info", "sim://wsg25")  # another profile: nothing to say
    assert "replaces" not in plain.stdout + plain.stderr, plain.stdout


def test_nothing_is_said_when_nothing_is_replaced(tmp_path: Path) -> None:
    (tmp_path / "mine.toml").write_text('name = "wsg50-mine"\nextends = "wsg50"\n')
    listed = _run(tmp_path, "profiles", "list")
    assert listed.returncode == 0 and "replaces" not in listed.stderr, listed.stderr
