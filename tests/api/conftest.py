"""Constants for the API tests; the `sim_process` fixture lives in tests/conftest.py."""

from __future__ import annotations

from pathlib import Path

ROOT = Path(__file__).resolve().parents[2]
SHIPPED = sorted(p.stem for p in (ROOT / "profiles").glob("*.toml"))
TIME_SCALE = 50
