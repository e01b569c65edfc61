"""Issue 43 §5: ``[transport] baudrate = 1e20`` in a profile passed ``profiles validate``, then ``open()``
raised OverflowError. A profile's baud rate is bounded as the URL's ``?baudrate=`` is (one rule:
grippers/settings.py RANGES, grippers/profile_model.py Baudrate)."""

from __future__ import annotations

import subprocess
import sys
from pathlib import Path

import pytest

from grippers.settings import RANGES

ROOT = Path(__file__).resolve().parents[2]


def _validate(tmp_path: Path, base: str, baudrate: int) -> subprocess.CompletedProcess[str]:
    path = tmp_path / f"{base}-x.toml"
    path.write_text(f'name = "{base}-x"\nextends = "{base}"\n[transport]\nbaudrate = {baudrate}\n')
    return subprocess.run(
        [sys.executable, "-m", "grippers", "profiles", "validate", str(path)],
        cwd=ROOT,
        capture_output=True,
        text=True,
        timeout=60,
    )


@pytest.mark.parametrize("base", ["wsg50", "msg-150", "robotiq-2f85"])
@pytest.mark.parametrize("baudrate", [10**20, 10**11, int(RANGES["baudrate"][1]) + 1, 0])
def test_an_absurd_baudrate_is_refused_by_validate(tmp_path: Path, base: str, baudrate: int) -> None:
    r = _validate(tmp_path, base, baudrate)
    assert r.returncode == 1, r.stdout + r.stderr
    assert "transport.baudrate" in r.stdout + r.stderr


@pytest.mark.parametrize("base", ["wsg50", "msg-150", "robotiq-2f85"])
def test_a_real_baudrate_passes(tmp_path: Path, base: str) -> None:
    r = _validate(tmp_path, base, 115200)
    assert r.returncode == 0, r.stdout + r.stderr
