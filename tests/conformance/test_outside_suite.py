"""The conformance suite as an outside plugin author uses it: one subclass in their own test file, run by
pytest in a fresh interpreter with no conftest of ours (issue 28 §5)."""

from __future__ import annotations

import subprocess
import sys
import textwrap
from pathlib import Path


def _pytest(folder: Path, *args: str) -> subprocess.CompletedProcess[str]:
    return subprocess.run(
        [
            sys.executable,
            "-m",
            "pytest",
            "-q",
            "-p",
            "no:cacheprovider",
            "-p",
            "no:randomly",
            *args,
            str(folder),
        ],
        cwd=folder,
        capture_output=True,
        text=True,
        timeout=300,
    )


def test_a_subclass_naming_its_target_runs_the_checks(tmp_path: Path) -> None:
    (tmp_path / "test_acme_conformance.py").write_text(
        textwrap.dedent(
            """
            from grippers.testing.conformance import ConformanceSuite

            class TestWsgConformance(ConformanceSuite):
                target = "wsg50"  # a profile name; "sim://wsg50?transport=udp" takes sim:// settings
            """
        )
    )
    done = _pytest(tmp_path, "-k", "completed_move or newer_motion or not_grasped")
    assert done.returncode == 0, done.stdout + done.stderr
    assert "3 passed" in done.stdout, done.stdout  # the imported base class is not collected on its own


def test_a_subclass_without_a_target_fails_saying_what_to_set(tmp_path: Path) -> None:
    (tmp_path / "test_forgot.py").write_text(
        "from grippers.testing.conformance import ConformanceSuite\n\n"
        "class TestForgot(ConformanceSuite):\n    pass\n"
    )
    done = _pytest(tmp_path, "-k", "completed_move")
    assert done.returncode == 1, done.stdout + done.stderr
    assert "set `target`, or parametrise conformance_target" in done.stdout, done.stdout
