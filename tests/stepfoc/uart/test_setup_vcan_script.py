"""scripts/setup-vcan.sh: shipped executable, valid shell, refuses bad names before touching anything."""

from __future__ import annotations

import os
import shutil
import subprocess
from pathlib import Path

import pytest

SCRIPT = Path(__file__).resolve().parents[3] / "scripts" / "setup-vcan.sh"
BASH = shutil.which("bash")

pytestmark = pytest.mark.skipif(BASH is None, reason="needs bash")


def test_executable_and_parses() -> None:
    assert os.access(SCRIPT, os.X_OK)
    subprocess.run([BASH, "-n", str(SCRIPT)], check=True, timeout=10)


def test_help_and_bad_name() -> None:
    out = subprocess.run([BASH, str(SCRIPT), "--help"], capture_output=True, text=True, timeout=10)
    assert out.returncode == 0 and "vcan0" in out.stdout
    bad = subprocess.run([BASH, str(SCRIPT), "no such name!"], capture_output=True, text=True, timeout=10)
    assert bad.returncode == 2 and "invalid interface name" in bad.stderr


WITH_VCAN = SCRIPT.parent / "with-vcan"
RUN_VCAN_TESTS = SCRIPT.parent / "run-vcan-tests.sh"


def test_with_vcan_and_runner_are_shipped_executable_and_parse() -> None:
    for script in (WITH_VCAN, RUN_VCAN_TESTS):
        assert os.access(script, os.X_OK), script
        subprocess.run([BASH, "-n", str(script)], check=True, timeout=10)


def test_with_vcan_usage() -> None:
    bare = subprocess.run([str(WITH_VCAN)], capture_output=True, text=True, timeout=10)
    assert bare.returncode == 2 and "with-vcan CMD" in bare.stdout
    helped = subprocess.run([str(WITH_VCAN), "--help"], capture_output=True, text=True, timeout=10)
    assert (
        helped.returncode == 0
        and "exit 3" not in helped.stdout
        and "3 with a one-line reason" in helped.stdout
    )


@pytest.mark.skipif(shutil.which("linux.uml") is None, reason="needs the user-mode-linux package")
def test_with_vcan_runs_the_command_where_vcan0_and_vcan1_are_up(tmp_path: Path) -> None:
    """The guest path (forced even where this kernel has vcan): CMD sees both interfaces up, gets this
    working directory, and its status, stdout and stderr come back separately."""
    env = {**os.environ, "WITH_VCAN_UML": "1", "WITH_VCAN_TIMEOUT": "120"}
    cmd = "cat /sys/class/net/vcan0/operstate /sys/class/net/vcan1/flags; pwd; echo oops >&2; exit 7"
    r = subprocess.run(
        [str(WITH_VCAN), BASH, "-c", cmd], cwd=tmp_path, env=env, capture_output=True, text=True, timeout=180
    )
    assert r.returncode == 7, r.stderr
    lines = r.stdout.split()
    # a vcan has no carrier to report ("unknown"); flags 0x..1 = IFF_UP
    assert lines[0] in ("unknown", "up") and int(lines[1], 16) & 1 and lines[2] == str(tmp_path)
    assert r.stderr.strip() == "oops"
