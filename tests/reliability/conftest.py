"""Fixtures for the reliability tests: simulators on real transports, leak snapshots and fuzz counters.

Test files import nothing from here (pytest runs with --import-mode=importlib); they ask for fixtures.
Hypothesis tests may only use session-scoped fixtures (``fuzz_count``), so the long mode
(``GRIPPERS_FUZZ=long``) runs them unchanged; the case counts are printed at the end of the run.
"""

from __future__ import annotations

import collections
import json
import os
import threading
import time
import uuid
from collections.abc import Callable, Iterator
from typing import Any

import pytest

from grippers.drivers.stepfoc.sim import MsgModel, serve_can, serve_uart
from grippers.drivers.wsg.client import WsgClient

from ..closing import closed_after

WSG_TIME_SCALE = 50.0
MSG_TIME_SCALE = 200.0  # an MSG calibration (~8 s simulated) then takes ~40 ms

_COUNTS: collections.Counter[str] = collections.Counter()
_STARTED = time.monotonic()


@pytest.fixture(scope="session")
def fuzz_count() -> collections.Counter[str]:
    """Examples run per fuzz target (``fuzz_count[target] += 1`` in a property test)."""
    return _COUNTS


def pytest_terminal_summary(terminalreporter: Any) -> None:
    if not _COUNTS:
        return
    total = sum(_COUNTS.values())
    terminalreporter.section("fuzz case counts")
    for name, n in sorted(_COUNTS.items()):
        terminalreporter.write_line(f"{n:>12,}  {name}")
    elapsed = time.monotonic() - _STARTED
    terminalreporter.write_line(f"{total:>12,}  total ({elapsed:.0f} s since the conftest loaded)")
    report = os.environ.get("GRIPPERS_FUZZ_REPORT")
    if report:
        with open(report, "w", encoding="utf-8") as fh:
            json.dump({"counts": dict(_COUNTS), "total": total, "seconds": round(elapsed, 1)}, fh, indent=1)


# ------------------------------------------------------------------------------------------------- leaks


def _fds() -> dict[str, str]:
    """Open descriptors and what they point to (the target tells a reused number from the same file)."""
    out = {}
    for fd in os.listdir("/proc/self/fd"):
        try:
            out[fd] = os.readlink(f"/proc/self/fd/{fd}")
        except OSError:  # closed meanwhile (e.g. the listdir's own descriptor)
            pass
    return out


class ResourceSnapshot:
    """Threads and file descriptors now; :meth:`leaks` says what appeared since (after a bounded wait)."""

    def __init__(self) -> None:
        self.threads = set(threading.enumerate())
        self.fds = _fds()

    def leaks(self, wait: float = 3.0) -> tuple[list[threading.Thread], list[str]]:
        deadline = time.monotonic() + wait
        while True:
            threads = [t for t in threading.enumerate() if t not in self.threads and t.is_alive()]
            fds = [
                f"{fd} -> {target}"
                for fd, target in sorted(_fds().items())
                if self.fds.get(fd) != target and not target.startswith("/proc/")
            ]
            if (not threads and not fds) or time.monotonic() >= deadline:
                return threads, fds
            time.sleep(0.02)


@pytest.fixture
def snapshot() -> Callable[[], ResourceSnapshot]:
    return ResourceSnapshot


# ------------------------------------------------------------------------------------------------- WSG


@pytest.fixture
def wsg_connect() -> Iterator[Callable[..., WsgClient]]:
    """``WsgClient.from_url(url, **kw)``; every client is closed after the test."""

    def connect(url: str, **kw: Any) -> WsgClient:
        kw.setdefault("timeout", 1.0)
        return WsgClient.from_url(url, **kw)

    with closed_after(connect) as started:
        yield started


# ------------------------------------------------------------------------------------------------- MSG


@pytest.fixture
def can_channel() -> str:
    return f"reliability-{uuid.uuid4().hex[:12]}"


@pytest.fixture
def msg_can_sim(can_channel: str) -> Iterator[Callable[..., Any]]:
    """Serve MSG models on this test's virtual CAN channel; closed after the test."""

    def start(*models: MsgModel, time_scale: float = MSG_TIME_SCALE) -> Any:
        listen = f"can://virtual/{can_channel}"
        return serve_can(list(models) or [MsgModel()], listen, time_scale=time_scale)

    with closed_after(start, simulator=True) as started:
        yield started


@pytest.fixture
def msg_uart_sim() -> Iterator[Callable[..., Any]]:
    def start(model: MsgModel | None = None, *, time_scale: float = MSG_TIME_SCALE) -> Any:
        return serve_uart(model or MsgModel(), "pty", time_scale=time_scale)

    with closed_after(start) as started:
        yield started
