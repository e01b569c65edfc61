"""Issue 39 §3: a gripper nobody references any more is closed on garbage collection, with a ResourceWarning,
as sockets and files are. Re-running ``g = grippers.open('sim://wsg50')`` in a notebook kernel left two
threads per gripper (the simulator's and the driver's reader) and the transport open behind it."""

from __future__ import annotations

import gc
import subprocess
import sys
import threading
import time
import warnings

import pytest

import grippers

FAMILIES = ["sim://wsg50", "sim://msg-150", "sim://robotiq-2f85"]
BOUND_S = 15.0  # the close runs on a thread of its own (grippers/unclosed.py): bounded, not instant


def threads_left(before: set[threading.Thread]) -> list[str]:
    """Threads started since ``before`` that still run, once they had ``BOUND_S`` to end."""
    deadline = time.monotonic() + BOUND_S
    while True:
        left = [t.name for t in threading.enumerate() if t not in before and t.is_alive()]
        if not left or time.monotonic() > deadline:
            return left
        time.sleep(0.05)


@pytest.mark.parametrize("url", FAMILIES)
def test_an_unreferenced_gripper_is_closed_with_a_resource_warning(url: str) -> None:
    gc.collect()
    before = set(threading.enumerate())
    g = grippers.open(url)
    assert [t for t in threading.enumerate() if t not in before], "the gripper runs threads of its own"
    name = g.name
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always", ResourceWarning)
        del g
        gc.collect()
    assert any(
        issubclass(w.category, ResourceWarning) and f"unclosed gripper {name}" in str(w.message)
        for w in caught
    ), [str(w.message) for w in caught]
    assert threads_left(before) == []


def test_a_closed_gripper_is_collected_without_a_warning() -> None:
    g = grippers.open("sim://wsg50")
    g.close()
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always", ResourceWarning)
        del g
        gc.collect()
    assert not [w for w in caught if "unclosed gripper" in str(w.message)]


def test_a_program_that_exits_with_grippers_open_ends() -> None:
    """Found with the finalizer: at interpreter exit a new thread never starts, and Python 3.11's
    ``Thread.start()`` then waits for ever, so a script that never closed its grippers hung at its end."""
    script = (
        "import asyncio, grippers, grippers.aio\n"
        "g = grippers.open('sim://wsg50')\n"
        "async def main():\n"
        "    global a\n"
        "    a = await grippers.aio.open('sim://wsg50')\n"
        "asyncio.run(main())\n"
        "print(g.state().width >= 0)\n"
    )
    r = subprocess.run([sys.executable, "-c", script], capture_output=True, text=True, timeout=60)
    assert r.returncode == 0 and r.stdout.strip() == "True", r.stderr
