"""Cancelling an awaited call that is not a motion leaves the connection usable at once (issue 23 §3,
issue 20 §2): ``wait_for(g.state(), 0.01)`` on a silent device, then the device answers again and the next
``await g.state()`` returns a state well within the connection's timeout, with no "still outstanding"
refusal, no wait for the abandoned exchange's timeout and no asyncio noise.

Before the fix the cancelled call's worker stayed blocked in the driver until its timeout (the WSG then also
refused the same command id for ``stale_ttl``), so the next state() took about the timeout or failed.
"""

from __future__ import annotations

import asyncio
import time
from typing import Any

import pytest

import grippers.aio

# A timeout long enough that "at once" and "after the old exchange's timeout" cannot be confused on a busy
# machine: the next state() must finish in well under half of it, which only an abandoned exchange allows
# (a blocked worker holds its slot for the full timeout, and for the WSG stale_ttl on top).
TIMEOUT = 6.0

URLS = {
    "wsg-tcp": "sim://wsg50?transport=tcp&time_scale=5",
    "msg-can": "sim://msg-150?transport=can&time_scale=5",
    "msg-uart": "sim://msg-150?transport=pty&time_scale=5",
}


def run(coro: Any) -> Any:
    return asyncio.run(asyncio.wait_for(coro, 120))


@pytest.mark.parametrize("name", list(URLS))
def test_a_cancelled_state_leaves_the_connection_usable_at_once(name: str) -> None:
    seen: list[dict[str, Any]] = []

    async def main() -> None:
        asyncio.get_running_loop().set_exception_handler(lambda _loop, context: seen.append(context))
        async with grippers.aio.open(URLS[name], timeout=TIMEOUT) as g:
            assert (await g.state()).width >= 0
            faults = g.sync.simulator.faults
            for _ in range(3):  # again and again: nothing accumulates
                faults.silent = True
                with pytest.raises(asyncio.TimeoutError):
                    await asyncio.wait_for(g.state(), 0.01)
                faults.silent = False
                began = time.monotonic()
                state = await g.state()
                took = time.monotonic() - began
                assert state.width >= 0
                assert took < TIMEOUT / 2, f"the next state() took {took:.2f} s (timeout {TIMEOUT} s)"

    run(main())
    assert not seen, seen


def test_a_cancelled_info_frees_its_worker() -> None:
    """Every worker of the pool given to cancelled calls at once: the next call still finds one free."""

    async def main() -> None:
        async with grippers.aio.open(URLS["wsg-tcp"], timeout=TIMEOUT) as g:
            await g.home()
            faults = g.sync.simulator.faults
            faults.silent = True
            for _ in range(grippers.aio.WORKERS + 1):
                with pytest.raises(asyncio.TimeoutError):
                    await asyncio.wait_for(g.temperature(), 0.01)
            faults.silent = False
            began = time.monotonic()
            assert (await g.temperature()) > 0
            assert time.monotonic() - began < TIMEOUT / 2

    run(main())
