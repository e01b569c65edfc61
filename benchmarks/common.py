"""What every benchmark shares: the result record, the table printer and the clocks.

Benchmarks compare against a baseline measured in the same run (a minimal reference, the vendor library, a raw
socket), so a slow or busy machine moves both numbers and the ratio stays meaningful.
"""

from __future__ import annotations

import os
import statistics
import sys
import time
from collections.abc import Callable
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

REPO = Path(__file__).resolve().parent.parent
if str(REPO) not in sys.path:  # run as a script: make `drivers`, `grippers` and `benchmarks` importable
    sys.path.insert(0, str(REPO))


@dataclass
class Result:
    """One line of the table. ``figure``/``baseline``/``ratio`` are already formatted with their units."""

    name: str
    figure: str
    baseline: str
    ratio: str
    target: str
    passed: bool
    notes: list[str] = field(default_factory=list)

    @property
    def verdict(self) -> str:
        return "PASS" if self.passed else "FAIL"


COLUMNS = ("target", "figure", "baseline", "ratio", "goal", "result")


def format_table(results: list[Result], *, notes: bool = True) -> str:
    rows = [COLUMNS] + [(r.name, r.figure, r.baseline, r.ratio, r.target, r.verdict) for r in results]
    widths = [max(len(row[i]) for row in rows) for i in range(len(COLUMNS))]
    lines = []
    for i, row in enumerate(rows):
        lines.append("  ".join(cell.ljust(w) for cell, w in zip(row, widths, strict=True)).rstrip())
        if notes and i:
            lines.extend(f"    {n}" for n in results[i - 1].notes)
    return "\n".join(lines)


def markdown_table(results: list[Result]) -> str:
    lines = ["| " + " | ".join(COLUMNS) + " |", "|" + "---|" * len(COLUMNS)]
    for r in results:
        lines.append(f"| {r.name} | {r.figure} | {r.baseline} | {r.ratio} | {r.target} | {r.verdict} |")
    return "\n".join(lines)


def best_rate(run: Callable[[], int], repeats: int) -> float:
    """Items per second of the fastest of ``repeats`` runs (``run`` returns how many items it did).

    The fastest run is the one least disturbed by the rest of the machine; both sides of a comparison use it.
    """
    best = 0.0
    for _ in range(repeats):
        t0 = time.perf_counter()
        n = run()
        dt = time.perf_counter() - t0
        best = max(best, n / dt)
    return best


def median(values: list[float]) -> float:
    return statistics.median(values)


def thread_cpu_clock(ident: int) -> Callable[[], float]:
    """A CPU-time clock of one thread of this process (Linux), to leave simulator threads out of a figure."""
    clock_id = time.pthread_getcpuclockid(ident)
    return lambda: time.clock_gettime(clock_id)


def rss_bytes() -> int:
    """Resident set size of this process now (Linux /proc)."""
    with open("/proc/self/statm") as f:
        return int(f.read().split()[1]) * os.sysconf("SC_PAGE_SIZE")


def us(seconds: float) -> str:
    return f"{seconds * 1e6:.1f} us"


def rate(per_s: float, unit: str) -> str:
    if per_s >= 1e6:
        return f"{per_s / 1e6:.2f} M {unit}/s"
    if per_s >= 1e3:
        return f"{per_s / 1e3:.1f} k {unit}/s"
    return f"{per_s:.0f} {unit}/s"


def serve_as_child(server: Any, where: str) -> None:
    """The child's side of :class:`SimChild`: print where ``server`` serves, serve until the parent closes our
    stdin, close it, and leave without the interpreter's shutdown (the simulator's threads)."""
    print(where, flush=True)
    sys.stdin.read()
    server.close()
    os._exit(0)


class SimChild:
    """A simulator serving in a child process (its own interpreter: it does not share our GIL), started as
    ``python benchmarks/SCRIPT FLAG``: the child prints where it serves on its first line (``.where``, which
    must start with ``prefix``) and serves until its stdin closes (``close()``)."""

    def __init__(self, script: str, flag: str, prefix: str) -> None:
        import subprocess
        import sys

        self._proc = subprocess.Popen(
            [sys.executable, str(REPO / "benchmarks" / script), flag],
            stdin=subprocess.PIPE,
            stdout=subprocess.PIPE,
            text=True,
        )
        assert self._proc.stdout is not None
        self.where = self._proc.stdout.readline().strip()
        if not self.where.startswith(prefix):
            self._proc.kill()
            raise RuntimeError(f"simulator child did not start: {self.where!r}")

    def close(self) -> None:
        import subprocess

        assert self._proc.stdin is not None
        self._proc.stdin.close()
        try:
            self._proc.wait(10)
        except subprocess.TimeoutExpired:
            self._proc.kill()
