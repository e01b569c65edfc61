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
