"""Fixtures for the tests on a real SocketCAN interface (``pytest -m vcan``).

They need ``vcan0`` and ``vcan1`` up, and root for the tests that set a link down and up: run them with
``scripts/run-vcan-tests.sh`` (via ``scripts/with-vcan``, which brings both up where the kernel lacks vcan).
Elsewhere every test here skips with the reason, so the normal suite stays green; the runner script fails
when any of them skipped.

Each test owns its node ids and CAN ids (no other test in this folder uses them), so one test's frames never
answer another's requests even when a previous test left a simulator behind by failing.
"""

from __future__ import annotations

import os
import queue
import shutil
import signal
import subprocess
import sys
import threading
import time
from collections.abc import Callable, Iterator
from pathlib import Path
from typing import IO

import pytest

ROOT = Path(__file__).resolve().parents[2]
FAST = "heartbeat_s=0.05&reconnect_backoff_s=0.02&reconnect_backoff_max_s=0.2"


def missing(interface: str = "vcan0") -> str | None:
    """Why the vcan tests cannot run here, or None."""
    if not sys.platform.startswith("linux"):
        return "SocketCAN exists only on Linux"
    if not os.path.exists(f"/sys/class/net/{interface}"):
        return f"no {interface} interface: run scripts/run-vcan-tests.sh (or scripts/setup-vcan.sh first)"
    return None


@pytest.fixture
def vcan() -> str:
    reason = missing("vcan0")
    if reason:
        pytest.skip(reason)
    return "vcan0"


@pytest.fixture
def vcan1() -> str:
    reason = missing("vcan1")
    if reason:
        pytest.skip(reason)
    return "vcan1"


def _ip(*args: str) -> None:
    subprocess.run(["ip", "link", *args], check=True, timeout=10, capture_output=True)


@pytest.fixture
def link() -> Iterator[Callable[..., None]]:
    """``link("vcan1", "down" | "up" | "delete" | "add")``: change an interface as an administrator (or an
    unplugged adapter) would. Whatever the test did, the interface is present and up again afterwards."""
    if shutil.which("ip") is None or os.geteuid() != 0:
        pytest.skip("needs root and iproute2 to set an interface down and up (scripts/run-vcan-tests.sh)")
    touched: set[str] = set()

    def change(name: str, what: str) -> None:
        touched.add(name)
        if what in ("up", "down"):
            _ip("set", name, what)
        elif what == "delete":
            _ip("delete", name)
        elif what == "add":
            _ip("add", "dev", name, "type", "vcan")
        else:
            raise ValueError(what)

    yield change
    for name in touched:
        if not os.path.exists(f"/sys/class/net/{name}"):
            _ip("add", "dev", name, "type", "vcan")
        _ip("set", name, "up")


def wait_until(predicate: Callable[[], bool], timeout: float, what: str) -> None:
    deadline = time.monotonic() + timeout
    while not predicate():
        if time.monotonic() > deadline:
            raise AssertionError(f"{what}: not within {timeout:g} s")
        time.sleep(0.01)


class Proc:
    """A ``python -m grippers`` subprocess; its stdout lines arrive in :attr:`lines` (a queue filled by a
    thread, so no line can hide in a read buffer between a ``readline`` and a later read of the pipe).
    With ``first_line`` the first line (a simulator's URL) is awaited and kept in :attr:`first`."""

    def __init__(self, args: list[str], first_line: bool) -> None:
        self.proc = subprocess.Popen(
            [sys.executable, "-m", "grippers", *args],
            cwd=ROOT,
            stdout=subprocess.PIPE,
            stderr=subprocess.PIPE,
            text=True,
            env={**os.environ, "PYTHONUNBUFFERED": "1"},
        )
        self.lines: queue.Queue[str] = queue.Queue()
        self._err: list[str] = []
        self._readers = [
            threading.Thread(target=self._pump, args=(self.proc.stdout, self.lines.put), daemon=True),
            threading.Thread(target=self._pump, args=(self.proc.stderr, self._err.append), daemon=True),
        ]
        for t in self._readers:
            t.start()
        self.first = ""
        if first_line:
            try:
                self.first = self.lines.get(timeout=60).strip()
            except queue.Empty:
                _, err = self.stop()
                raise AssertionError(f"{args}: printed nothing within 60 s ({err})") from None

    @staticmethod
    def _pump(stream: IO[str] | None, put: Callable[[str], None]) -> None:
        assert stream is not None
        for line in stream:
            put(line)

    def stop(self) -> tuple[str, str]:
        """SIGINT (the CLI's Ctrl-C path, which ends cleanly); returns the stdout lines not taken, stderr."""
        if self.proc.poll() is None:
            self.proc.send_signal(signal.SIGINT)
        try:
            self.proc.wait(timeout=20)
        except subprocess.TimeoutExpired:
            self.proc.kill()
            self.proc.wait(timeout=10)
        for t in self._readers:
            t.join(10)
        out = []
        while not self.lines.empty():
            out.append(self.lines.get_nowait())
        return "".join(out), "".join(self._err)


@pytest.fixture
def grippers_proc() -> Iterator[Callable[..., Proc]]:
    """Start ``grippers ARGS...`` in the background; stopped with SIGINT at the end of the test."""
    procs: list[Proc] = []

    def start(*args: str, first_line: bool = True) -> Proc:
        p = Proc(list(args), first_line)
        procs.append(p)
        return p

    yield start
    for p in procs:
        p.stop()


def run_cli(*args: str, timeout: float = 60) -> subprocess.CompletedProcess[str]:
    return subprocess.run(
        [sys.executable, "-m", "grippers", *args],
        cwd=ROOT,
        capture_output=True,
        text=True,
        timeout=timeout,
        env={**os.environ, "PYTHONUNBUFFERED": "1"},
    )
