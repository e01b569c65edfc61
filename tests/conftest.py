"""Shared test settings.

Hypothesis runs a bounded number of examples so CI stays fast; ``GRIPPERS_FUZZ=long`` switches to the
on-demand long mode (see docs/reliability.md).
"""

from __future__ import annotations

import contextlib
import os
import re
import select
import signal
import subprocess
import sys
import time
from collections.abc import Callable, Iterator
from pathlib import Path
from typing import Any

import pytest
from hypothesis import HealthCheck, settings

from .closing import closed_after

settings.register_profile(
    "ci",
    max_examples=150,
    deadline=None,
    suppress_health_check=[HealthCheck.too_slow],
)
settings.register_profile(
    "long",
    max_examples=1_000_000,
    deadline=None,
    suppress_health_check=list(HealthCheck),
)
LONG = os.environ.get("GRIPPERS_FUZZ") == "long"
settings.load_profile("long" if LONG else "ci")
# GRIPPERS_FUZZ_EXAMPLES=N sets the long mode's count, for a long run of chosen targets (a million examples of
# the slow ones takes half an hour on 2 cores).
if LONG and os.environ.get("GRIPPERS_FUZZ_EXAMPLES"):
    settings.register_profile(
        "long-n", settings.get_profile("long"), max_examples=int(os.environ["GRIPPERS_FUZZ_EXAMPLES"])
    )
    settings.load_profile("long-n")


# Tests that share a host-wide resource run one after another on one pytest-xdist worker (``--dist
# loadgroup``, the README's test command): python-can's udp_multicast bus is one UDP port for every group
# (docs/protocols.md §2), and the README's examples listen on the fixed ports they print.
_SERIAL_FILES = {
    "test_readme_examples.py": "fixed-ports",
    "test_udp_multicast.py": "udp_multicast",
    "test_reconnect_msg_can.py": "udp_multicast",
}


# Module-scoped fixtures that take seconds to build (a pip install, a served Zenoh session): their tests share
# a worker, so the fixture is built once, not once per worker that happens to run one of them (``--dist
# loadgroup`` otherwise hands each test to any worker). Key: the module's path below tests/ and the fixture.
_SHARED_MODULE_FIXTURES = {
    ("cli/test_plugin_example.py", "plugin_site"),
    ("remote/test_cli.py", "server"),
}
_TESTS = Path(__file__).resolve().parent


def _serial_group(item: pytest.Item) -> str | None:
    fixtures = getattr(item, "fixturenames", ())
    if item.get_closest_marker("udp_multicast") or "mcast_channel" in fixtures:
        return "udp_multicast"
    if "udp_multicast" in item.name:
        return "udp_multicast"
    if item.path.name in _SERIAL_FILES:
        return _SERIAL_FILES[item.path.name]
    module = item.path.relative_to(_TESTS).as_posix() if item.path.is_relative_to(_TESTS) else ""
    for path, fixture in _SHARED_MODULE_FIXTURES:
        if module == path and fixture in fixtures:
            return f"{path}::{fixture}"
    return None


WORKERS_PER_CORE = 2


def pytest_xdist_auto_num_workers(config: pytest.Config) -> int | None:
    """``-n auto`` (the README's test command) starts two workers per core the process may use: the suite
    mostly waits (simulators at real time, subprocesses starting, timeouts running out), so one worker per
    core leaves the cores idle much of the time. ``PYTEST_XDIST_AUTO_NUM_WORKERS=N`` (pytest-xdist's own)
    overrides it; docs/reliability.md has the measurements."""
    if os.environ.get("PYTEST_XDIST_AUTO_NUM_WORKERS"):
        return None  # pytest-xdist's own hook reads it
    try:
        cores = len(os.sched_getaffinity(0))
    except AttributeError:  # not Linux
        cores = os.cpu_count() or 1
    return WORKERS_PER_CORE * cores


@pytest.hookimpl(tryfirst=True)  # before pytest-xdist reads the groups
def pytest_collection_modifyitems(items: list[pytest.Item]) -> None:
    """Long mode: no pytest-timeout (120 s in pyproject.toml); a million examples take many minutes.
    Under pytest-xdist, the tests of one host-wide resource share a group (see ``_serial_group``)."""
    for item in items:
        if LONG:
            item.add_marker(pytest.mark.timeout(0))
        group = _serial_group(item)
        if group:
            item.add_marker(pytest.mark.xdist_group(group))


# A suite started in the background by a non-interactive shell (`cmd &` in a CI script, nohup) inherits SIGINT
# ignored, and Python then never raises KeyboardInterrupt, here or in the `grippers` processes the tests start
# (an ignored signal stays ignored across exec). The Ctrl-C tests need Ctrl-C delivered as a terminal does:
# Python's own handler here, and so the default disposition in every child.
if signal.getsignal(signal.SIGINT) is signal.SIG_IGN:
    signal.signal(signal.SIGINT, signal.default_int_handler)

ROOT = Path(__file__).resolve().parents[1]
START_TIMEOUT = 20.0  # seconds for a simulator subprocess to print its URL


class SimProcess:
    """A ``grippers sim ...`` subprocess and the URL it printed on its first line (CLI and API tests)."""

    def __init__(self, *args: str) -> None:
        self.args = args
        self.proc = subprocess.Popen(
            [sys.executable, "-m", "grippers", "sim", *args],
            cwd=ROOT,
            stdout=subprocess.PIPE,
            stderr=subprocess.PIPE,
            text=True,
            env={**os.environ, "PYTHONUNBUFFERED": "1"},
        )
        self.url = self._read_url()

    def _read_url(self) -> str:
        assert self.proc.stdout is not None
        fd = self.proc.stdout.fileno()
        seen = ""
        waited = 0.0
        while waited < START_TIMEOUT:
            ready, _, _ = select.select([fd], [], [], 0.2)
            waited += 0.2
            if not ready:
                if self.proc.poll() is not None:
                    break
                continue
            line = self.proc.stdout.readline()
            if not line:
                break
            seen += line
            m = re.search(r"serving at (\S+)", line)
            if m:
                return m.group(1)
        self.close()
        err = self.proc.stderr.read() if self.proc.stderr else ""
        raise RuntimeError(f"simulator {self.args} printed no URL: {seen!r} {err[-2000:]!r}")

    @contextlib.contextmanager
    def held(self) -> Iterator[None]:
        """The simulated clock held still for the body (SIGUSR1, SIGUSR2 after; grippers/cli/sim_common.py),
        each confirmed by the simulator before this goes on: the device stands still, and answers."""
        self._signal(signal.SIGUSR1, "clock held")
        try:
            yield
        finally:
            self._signal(signal.SIGUSR2, "clock running")

    def _signal(self, sig: int, confirmation: str) -> None:
        """Send ``sig`` and read stderr (raw, unbuffered: a buffered reader would hide a second line from
        ``select``) until the simulator confirms."""
        assert self.proc.stderr is not None
        self.proc.send_signal(sig)
        fd = self.proc.stderr.fileno()
        seen = b""
        deadline = time.monotonic() + START_TIMEOUT
        while time.monotonic() < deadline:
            ready, _, _ = select.select([fd], [], [], 0.2)
            if ready:
                chunk = os.read(fd, 4096)
                if not chunk:
                    break
                seen += chunk
                if confirmation.encode() in seen:
                    return
        raise AssertionError(f"simulator {self.args}: no {confirmation!r} after signal {sig}: {seen!r}")

    def close(self) -> None:
        if self.proc.poll() is None:
            self.proc.terminate()
            try:
                self.proc.wait(timeout=5)
            except subprocess.TimeoutExpired:
                self.proc.kill()
                self.proc.wait(timeout=5)
        for stream in (self.proc.stdout, self.proc.stderr):
            if stream:
                stream.close()


@pytest.fixture
def sim_process() -> Iterator[Callable[..., SimProcess]]:
    """``sim_process("wsg", "--listen", "tcp://127.0.0.1:0")``: started now, stopped after the test."""
    with closed_after(SimProcess) as start:
        yield start


@pytest.fixture
def wsg_sim() -> Iterator[Callable[..., Any]]:
    """``wsg_sim(listen, time_scale=50, **model_kw)``: a WSG simulator (``serve(WsgModel(**model_kw))``) at
    the driver level; every server is closed after the test, which fails if a simulator thread died (a crash
    in the simulator must not pass for a device that went silent). Profile-level tests use ``gripper_sim``
    (grippers/testing/) instead."""
    from grippers.drivers.wsg.sim import WsgModel, serve

    def start(listen: str = "tcp://127.0.0.1:0", *, time_scale: float = 50.0, **model_kw: Any) -> Any:
        return serve(WsgModel(**model_kw), listen, time_scale=time_scale)

    with closed_after(start, simulator=True) as started:
        yield started
