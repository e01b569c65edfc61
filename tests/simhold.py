"""Holding a simulated device still while a test acts (issue 33 §5).

A test of a timing window (a motion still running when a newer command, a stop or an e-stop arrives) must not
race the simulator's scaled clock against the scheduler: on a busy machine the test can be kept from acting
for longer than the whole motion lasts. Instead the test pauses the simulator's clock before it starts the
motion, moves the clock on step by step until the motion is observably under way, acts, and only then lets
the clock run again. The client's own bounds run on the wall clock, so a hold lasts only as long as the
test needs to act (milliseconds), far below any client timeout or stall bound.
"""

from __future__ import annotations

import contextlib
import linecache
import sys
import threading
import time
from collections.abc import Callable, Iterator
from typing import Any

from grippers.drivers.simkit import SimClock


def clock_of(sim: Any) -> SimClock:
    """The clock of a simulator server, or of the one serving a ``sim://`` gripper (``.simulator``)."""
    server = getattr(sim, "simulator", None) or sim
    clock: SimClock = server.clock
    return clock


# An MSG simulator's held clock creeps 1 ms per reading: a poll that reaches the firmware within one control
# tick of a new command would otherwise cancel the command's at-position reset (SimClock.pause's docstring).
MSG_CREEP_S = 0.001


@contextlib.contextmanager
def held(sim: Any, *, creep: float = 0.0) -> Iterator[SimClock]:
    """The simulator's clock paused for the body (moved on only by :func:`step_until` and ``creep`` per
    reading), then running."""
    clock = clock_of(sim)
    clock.pause(creep=creep)
    try:
        yield clock
    finally:
        clock.resume()


def step_until(
    clock: SimClock, predicate: Callable[[], bool], what: str, *, step: float = 0.02, limit: float = 20.0
) -> None:
    """Move the paused ``clock`` on ``step`` simulated seconds at a time until ``predicate()`` (which asks the
    device, so the model advances to the clock); AssertionError after ``limit`` simulated seconds."""
    for _ in range(int(limit / step) + 1):
        if predicate():
            return
        clock.step(step)
    raise AssertionError(f"{what}: not within {limit:g} simulated s")


def under_way(g: Any, start: float, *, by: float = 5e-4) -> Callable[[], bool]:
    """A predicate: the gripper reports moving and its jaws left ``start`` (m) by more than ``by``."""

    def moving() -> bool:
        st = g.state()
        return bool(st.moving) and abs(st.width - start) > by

    return moving


def wait_until_at_lock(thread: threading.Thread, *, timeout: float = 10.0) -> None:
    """Return once ``thread`` waits at a ``with self.lock:`` line (a lock the caller holds: it stays there).

    A simulator's thread checks for close() between its locked steps: a test that holds the lock and closes
    the simulator must first see the thread past that check, or the thread may leave without ever waiting.
    """
    deadline = time.monotonic() + timeout
    while time.monotonic() < deadline:
        frame = sys._current_frames().get(thread.ident or 0)
        if frame is not None:
            line = linecache.getline(frame.f_code.co_filename, frame.f_lineno).strip()
            if line == "with self.lock:":
                return
        time.sleep(0.002)
    raise AssertionError(f"{thread.name} never came to wait for its lock")
