"""grippers.aio keeps the threaded API's rules (issue 20 §2, issue 23 §3): the newer motion wins in
call order, a handle needs one await, cancelling during close() ends in CancelledError, no "never
retrieved" noise, and the methods cannot drift from Gripper's."""

from __future__ import annotations

import asyncio
import gc
from typing import Any

import pytest

import grippers
import grippers.aio
from grippers import CommandFailed
from grippers.aio import AsyncMotionHandle

URLS = ["sim://wsg50?time_scale=5", "sim://msg-150?time_scale=5"]


def run(coro: Any) -> Any:
    return asyncio.run(asyncio.wait_for(coro, 60))


@pytest.mark.parametrize("url", URLS)
def test_the_newer_motion_wins_in_call_order(url: str) -> None:
    async def main() -> None:
        async with grippers.aio.open(url) as g:
            await g.home()
            top = g.limits.max_width
            for _ in range(5):
                await g.move(top * 0.2)
                first = await g.move(top * 0.6, g.limits.min_speed * 2, wait=False)
                assert isinstance(first, AsyncMotionHandle)
                second = await g.move(top * 0.9)  # the newer call: it must be the one that completes
                assert abs(second.width - top * 0.9) < 1.5e-3
                with pytest.raises(CommandFailed, match="superseded"):
                    await first  # one await: the handle itself

    run(main())


def test_a_superseded_handle_nobody_awaits_makes_no_noise() -> None:
    seen: list[dict[str, Any]] = []

    async def main() -> None:
        asyncio.get_running_loop().set_exception_handler(lambda _loop, context: seen.append(context))
        async with grippers.aio.open(URLS[0]) as g:
            await g.home()
            await g.move(0.1, g.limits.min_speed * 2, wait=False)  # dropped on the floor
            await g.move(0.02)
        gc.collect()
        await asyncio.sleep(0)

    run(main())
    gc.collect()
    assert not seen, seen


@pytest.mark.parametrize("url", URLS)
def test_a_motion_cancelled_while_close_runs_ends_cancelled(url: str) -> None:
    async def main() -> None:
        g = await grippers.aio.open(url)
        await g.home()
        task = asyncio.ensure_future(g.move(g.limits.max_width * 0.9, g.limits.min_speed * 2))
        await asyncio.sleep(0.05)  # let the motion start (registration happens in the task)
        closing = asyncio.ensure_future(g.close())
        await asyncio.sleep(0)
        task.cancel()
        with pytest.raises(asyncio.CancelledError):
            await task
        await closing

    run(main())


def test_cancelling_a_motion_leaves_the_gripper_usable() -> None:
    async def main() -> None:
        async with grippers.aio.open(URLS[0]) as g:
            await g.home()
            with pytest.raises(asyncio.TimeoutError):
                await asyncio.wait_for(g.move(0.1, g.limits.min_speed), 0.1)
            result = await g.move(0.03)
            assert abs(result.width - 0.03) < 1e-3

    run(main())


# That every public Gripper method has its asyncio twin with the same parameters is checked against the one
# declaration of the commands, grippers/commands.py, in tests/test_command_table.py.


@pytest.mark.parametrize("url", URLS)
def test_servo_takes_over_from_an_awaited_move(url: str) -> None:
    async def main() -> None:
        async with grippers.aio.open(url) as g:
            await g.home()
            top = g.limits.max_width
            await g.move(top * 0.2)
            moving = asyncio.ensure_future(g.move(top * 0.9, g.limits.min_speed * 2))
            while abs((await g.state()).width - top * 0.2) < 1e-3:
                await asyncio.sleep(0.01)
            await g.servo(top * 0.5)
            with pytest.raises(CommandFailed, match="superseded by servo"):
                await moving

    run(main())
