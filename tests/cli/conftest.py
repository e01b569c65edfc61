"""Fixtures for the CLI tests: the CLI and the simulators run as subprocesses over real transports.

Simulators print the URL they serve on their first line; tests parse it. Every wait has a timeout; every
process, socket and pty is closed by its fixture. Helpers are fixtures (pytest runs with
``--import-mode=importlib``, so test modules cannot import each other).
"""

from __future__ import annotations

import contextlib
import functools
import itertools
import json
import os
import random
import re
import select
import signal
import socket
import subprocess
import sys
import threading
from collections.abc import Callable, Iterator
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import pytest

from grippers.cli.schemas import validate

ROOT = Path(__file__).resolve().parents[2]
PYTHON = sys.executable
TIME_SCALE = "50"  # simulated seconds per wall-clock second


@dataclass
class Result:
    argv: tuple[str, ...]
    returncode: int
    stdout: str
    stderr: str

    def json(self) -> dict[str, Any]:
        doc = json.loads(self.stdout)
        validate(doc)  # every --json document is checked against its schema
        return doc

    def json_lines(self) -> list[dict[str, Any]]:
        docs = [json.loads(line) for line in self.stdout.splitlines() if line.strip()]
        for doc in docs:
            validate(doc)
        return docs

    def one_error_line(self) -> str:
        lines = [line for line in self.stderr.splitlines() if line.strip()]
        assert len(lines) == 1, self.stderr
        assert "Traceback" not in self.stderr
        return lines[0]


def _env() -> dict[str, str]:
    return {**os.environ, "PYTHONUNBUFFERED": "1"}


def _run(*args: str, timeout: float = 30.0, stdin: str | None = None) -> Result:
    proc = subprocess.run(
        [PYTHON, "-m", "grippers", *args],
        cwd=ROOT,
        capture_output=True,
        text=True,
        timeout=timeout,
        input=stdin,
        env=_env(),
    )
    return Result(args, proc.returncode, proc.stdout, proc.stderr)


@pytest.fixture
def cli() -> Callable[..., Result]:
    """``cli("probe", "sim://", timeout=30)``: run ``python -m grippers`` in a subprocess, bounded."""
    return _run


@pytest.fixture
def cli_json(cli: Callable[..., Result]) -> Callable[..., dict[str, Any]]:
    """Run a command with ``--json``, require exit 0 and a document valid against its schema."""

    def run(*args: str, timeout: float = 30.0) -> dict[str, Any]:
        r = cli(*args, "--json", timeout=timeout)
        assert r.returncode == 0, (args, r.stdout, r.stderr)
        return r.json()

    return run


@pytest.fixture
def start_sim(sim_process: Callable[..., Any]) -> Callable[..., Any]:
    """``start_sim("wsg", "--listen", "tcp://127.0.0.1:0")``; ``--time-scale`` is added for speed."""
    return lambda *args: sim_process(*args, "--time-scale", TIME_SCALE)


class _TcpServer:
    """A loopback TCP server that accepts and either stays silent or sends random bytes."""

    def __init__(self, garbage: bool) -> None:
        self.garbage = garbage
        self.sock = socket.create_server(("127.0.0.1", 0))
        self.sock.settimeout(0.05)
        self.port = self.sock.getsockname()[1]
        self._stop = threading.Event()
        self._conns: list[socket.socket] = []
        self._thread = threading.Thread(target=self._serve, daemon=True)
        self._thread.start()

    def _serve(self) -> None:
        rng = random.Random(7)
        while not self._stop.is_set():
            try:
                conn, _ = self.sock.accept()
                conn.setblocking(False)
                self._conns.append(conn)
            except TimeoutError:
                pass
            except OSError:
                return
            for conn in list(self._conns):
                try:
                    conn.recv(4096)
                except OSError:
                    pass
                if self.garbage:
                    try:
                        conn.send(bytes(rng.randrange(256) for _ in range(64)))
                    except OSError:
                        pass

    def close(self) -> None:
        self._stop.set()
        self._thread.join(timeout=5)
        for conn in self._conns:
            conn.close()
        self.sock.close()


class _Pty:
    """A pseudo-terminal whose far end is silent or sends random bytes; ``path`` is the port to probe."""

    def __init__(self, garbage: bool) -> None:
        self.master, self.slave = os.openpty()
        self.path = os.ttyname(self.slave)
        self._stop = threading.Event()
        self._thread = threading.Thread(target=self._serve, args=(garbage,), daemon=True)
        self._thread.start()

    def _serve(self, garbage: bool) -> None:
        rng = random.Random(11)
        while not self._stop.is_set():
            ready, _, _ = select.select([self.master], [], [], 0.02)
            try:
                if ready:
                    os.read(self.master, 4096)
                if garbage:
                    os.write(self.master, bytes(rng.randrange(256) for _ in range(32)))
            except OSError:
                self._stop.wait(0.02)

    def close(self) -> None:
        self._stop.set()
        self._thread.join(timeout=5)
        os.close(self.master)
        os.close(self.slave)


def _closed_after_the_test(name: str, make: Callable[[], Any]) -> Any:
    """A fixture named ``name`` handing out ``make()``, closed after the test."""

    def fixture() -> Iterator[Any]:
        with contextlib.closing(make()) as thing:
            yield thing

    return pytest.fixture(name=name)(fixture)


silent_tcp = _closed_after_the_test("silent_tcp", functools.partial(_TcpServer, garbage=False))
garbage_tcp = _closed_after_the_test("garbage_tcp", functools.partial(_TcpServer, garbage=True))
silent_pty = _closed_after_the_test("silent_pty", functools.partial(_Pty, garbage=False))
garbage_pty = _closed_after_the_test("garbage_pty", functools.partial(_Pty, garbage=True))


class MonitorProxy:
    """What :func:`monitor_proxy` yields: the port it listens on; after the block, its standard output."""

    port = 0
    out = ""


@contextlib.contextmanager
def monitor_proxy(*args: str, stop_timeout: float) -> Iterator[MonitorProxy]:
    """``grippers monitor ARGS`` as a relay, from the moment it listens until Ctrl-C as the block ends."""
    proc = subprocess.Popen(
        [sys.executable, "-m", "grippers", "monitor", *args],
        cwd=ROOT,
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,
        text=True,
    )
    proxy = MonitorProxy()
    try:
        assert proc.stderr is not None
        line = proc.stderr.readline()  # "proxy listening on HOST:PORT, ..."
        port = re.search(r"listening on [^:]+:(\d+)", line)
        assert port, line
        proxy.port = int(port.group(1))
        yield proxy
    finally:
        proc.send_signal(signal.SIGINT)
        proxy.out, _ = proc.communicate(timeout=stop_timeout)


_groups = itertools.count(1)


@pytest.fixture
def mcast_channel() -> str:
    """A multicast group for this test. Groups do not isolate on Linux (docs/protocols.md §2 "Testing without
    CAN hardware"), so the tests also use node ids and WSG CAN ids no other test uses."""
    pytest.importorskip("msgpack", reason="python-can's udp_multicast interface needs msgpack")
    return f"239.74.{150 + os.getpid() % 50}.{next(_groups)}"


@pytest.fixture(autouse=True)
def _forget_the_example_plugins() -> Iterator[None]:
    """The example plugins (tests/cli/test_plugin_example.py, test_plugin_worked_example.py) both install a
    family ``acme`` (from modules of their own, acme_grippers and acme_r1): after each test the backend found
    is forgotten, so a later test in the same worker never meets the other's (a CI run met the small example's
    ``acme`` in tests/remote)."""
    yield
    import grippers.backends

    grippers.backends._cache.pop("acme", None)
