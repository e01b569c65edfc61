"""Issue 15: the asyncio face works over ``zenoh://`` as over any backend (a served WSG)."""

from __future__ import annotations

import asyncio
from collections.abc import Callable

import pytest

import grippers.aio
from grippers import CommandFailed

from .conftest import ServeProcess, sim


async def _stop_soon(g: grippers.aio.AsyncGripper) -> None:
    await asyncio.sleep(0.05)
    await g.stop()


def test_asyncio_over_zenoh(serve: Callable[..., ServeProcess]) -> None:
    server = serve(f"left={sim('wsg50', part_width_mm=40)}")

    async def main() -> None:
        async with grippers.aio.open(server.urls["left"]) as g:
            await g.home()
            assert (await g.move(0.06)).width == pytest.approx(0.06, abs=0.001)
            handle = await g.move(0.10, speed=0.005, wait=False)  # away from the part, slowly
            await asyncio.sleep(0.05)
            await handle.cancel()  # stops the device first, as for any backend
            with pytest.raises(asyncio.CancelledError):
                await handle.wait(5.0)
            with pytest.raises(CommandFailed, match="aborted"):  # a blocking motion stopped by another call
                await asyncio.gather(g.move(0.10, speed=0.005), _stop_soon(g))
            states = await asyncio.gather(*(g.state() for _ in range(20)))
            assert all(not s.moving for s in states[-1:])
            grasp = await g.grasp(0.04, force=20)
            assert grasp.grasped
            async for state in g.stream(rate_hz=50):
                assert state.width == pytest.approx(0.04, abs=0.001)
                break

    asyncio.run(main())


def test_a_remote_stream_takes_timeouts_as_a_local_one(serve: Callable[..., ServeProcess]) -> None:
    """Issue 13 item 7 holds for zenoh:// streams too: a huge timeout is capped (no OverflowError), a NaN
    one is a LimitError."""
    server = serve(f"left={sim('wsg50')}")
    with grippers.open(server.urls["left"]) as g, g.stream(rate_hz=50) as stream:
        with pytest.raises(grippers.LimitError):
            stream.get(float("nan"))
        assert stream.get(1e10).width >= 0
