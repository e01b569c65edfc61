"""grippers.aio against the simulators over real transports (loopback TCP, virtual CAN, a pty)."""

from __future__ import annotations

import asyncio
import threading
import time

import pytest

import grippers
import grippers.aio
from grippers import CommandFailed, GripperError, LimitError

URLS = [
    "sim://wsg50?time_scale=10",
    "sim://msg-150?time_scale=10",
    "sim://msg-150?time_scale=10&transport=pty",
]


def run(coro):  # noqa: ANN001, ANN201 - a tiny helper, no pytest-asyncio needed
    return asyncio.run(asyncio.wait_for(coro, 30))


@pytest.mark.parametrize("url", URLS)
def test_every_method_is_awaitable(url: str) -> None:
    async def main() -> None:
        async with grippers.aio.open(url) as g:
            await g.home()
            result = await g.move(0.04)
            assert abs(result.width - 0.04) < 1e-3
            st = await g.state()
            assert abs(st.width - 0.04) < 1e-3 and not st.moving
            info = await g.info()
            assert info.url
            grasp = await g.grasp(0.01, force=g.limits.min_force)
            assert grasp.width < 0.04
            await g.release()
            await g.stop()
            handle = await g.move(0.03, wait=False)
            assert abs((await handle).width - 0.03) < 1e-3
        assert g.sync._closed

    run(main())


def test_limits_raise_before_anything_is_queued() -> None:
    async def main() -> None:
        async with grippers.aio.open(URLS[0]) as g:
            with pytest.raises(LimitError):
                await g.move(1.0, wait=False)
            with pytest.raises(LimitError):
                await g.grasp(0.02, force=-1)

    run(main())


def test_100_concurrent_calls_add_no_thread() -> None:
    async def main() -> None:
        async with grippers.aio.open(URLS[0]) as g:
            await g.home()
            await g.state()
            before = threading.active_count()
            peak = before

            async def sample() -> None:
                nonlocal peak
                while True:
                    peak = max(peak, threading.active_count())
                    await asyncio.sleep(0)

            sampler = asyncio.ensure_future(sample())
            handle = await g.move(0.02, wait=False)
            states = await asyncio.gather(*(g.state() for _ in range(100)))
            await handle
            sampler.cancel()
            assert len(states) == 100
            # The WSG client's reader may wake for the pending motion: the backend's own reader, nothing more.
            assert peak <= before + 1, (before, peak, [t.name for t in threading.enumerate()])

    run(main())


@pytest.mark.parametrize("url", URLS[:2])
def test_cancelling_the_awaiting_task_stops_the_motion_first(url: str) -> None:
    async def main() -> None:
        async with grippers.aio.open(url) as g:
            await g.home()
            await g.move(0.07)
            slow = g.limits.min_speed * 2
            task = asyncio.ensure_future(g.move(0.005, slow))
            await asyncio.sleep(0.15)
            task.cancel()
            with pytest.raises(asyncio.CancelledError):
                await task
            # Stopped before CancelledError came out: the fingers stand still right away.
            a = (await g.state()).width
            await asyncio.sleep(0.2)
            b = await g.state()
            assert abs(b.width - a) < 1e-3 and not b.moving
            assert 0.01 < b.width < 0.07

    run(main())


def test_handle_cancel_and_wait() -> None:
    async def main() -> None:
        async with grippers.aio.open(URLS[0]) as g:
            await g.home()
            handle = await g.move(0.005, g.limits.min_speed, wait=False)
            with pytest.raises(GripperError):
                await handle.wait(0.05)  # still running: a timeout, the motion goes on
            assert not handle.done()
            await handle.cancel()
            assert handle.done()
            st = await g.state()
            assert not st.moving

    run(main())


def test_stream_is_an_async_iterator_without_a_thread() -> None:
    async def main() -> None:
        async with grippers.aio.open(URLS[0]) as g:
            await g.home()
            before = threading.active_count()
            got = []
            t0 = time.monotonic()
            async for st in g.stream(100):
                got.append(st)
                if len(got) == 10:
                    break
            assert threading.active_count() == before
            assert all(isinstance(s, grippers.GripperState) for s in got)
            assert time.monotonic() - t0 >= 0.08  # paced at the rate, not as fast as possible

    run(main())


def test_device_errors_come_through_typed() -> None:
    async def main() -> None:
        async with grippers.aio.open(URLS[0]) as g:
            with pytest.raises(CommandFailed):
                await g.move(0.03)  # not referenced yet: E_NOT_INITIALIZED

    run(main())


def test_awaiting_open_and_servo() -> None:
    async def main() -> None:
        g = await grippers.aio.open(URLS[0])
        try:
            await g.home()
            for i in range(50):
                await g.servo(0.02 + i * 0.0004)
                await asyncio.sleep(0.002)
            assert g.sync.servo_flush(2.0)
            await asyncio.sleep(0.2)
            assert abs((await g.state()).width - 0.0396) < 1e-3
        finally:
            await g.close()
        with pytest.raises(GripperError):
            await g.state()

    run(main())
