"""Target 6: wall time of ``grippers --help`` above a bare interpreter start, both measured here.

Both are started the same way (fresh processes, alternately, median of many), so interpreter start-up, disk
cache and machine load cancel out and the difference is what importing the CLI costs.
"""

from __future__ import annotations

import os
import subprocess
import sys
import time
from pathlib import Path

from benchmarks.common import REPO, Result, median

LIMIT_S = 0.25


def _entry_point() -> list[str]:
    script = Path(sys.executable).with_name("grippers")
    if script.exists():
        return [str(script), "--help"]
    return [sys.executable, "-m", "grippers", "--help"]  # not installed as a script: the same code path


def _wall(cmd: list[str]) -> float:
    t0 = time.perf_counter()
    subprocess.run(cmd, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL, check=True, cwd=REPO)
    return time.perf_counter() - t0


def run(quick: bool = False) -> list[Result]:
    n = 7 if quick else 21
    help_cmd = _entry_point()
    bare_cmd = [sys.executable, "-c", "pass"]
    env_note = "" if "PYTHONPATH" not in os.environ else " (PYTHONPATH set)"
    _wall(help_cmd), _wall(bare_cmd)  # warm the page cache and the .pyc files
    helps, bares = [], []
    for _ in range(n):
        helps.append(_wall(help_cmd))
        bares.append(_wall(bare_cmd))
    h, b = median(helps), median(bares)
    extra = h - b
    return [
        Result(
            "6 start-up: grippers --help",
            f"{h * 1000:.0f} ms",
            f"{b * 1000:.0f} ms (python -c pass)",
            f"+{extra * 1000:.0f} ms",
            f"<= +{LIMIT_S * 1000:.0f} ms",
            extra <= LIMIT_S,
            [
                f"median of {n} alternating runs of `{Path(help_cmd[0]).name} {' '.join(help_cmd[1:])}`"
                f"{env_note}"
            ],
        )
    ]
