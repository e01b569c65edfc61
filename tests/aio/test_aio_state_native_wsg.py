"""``await g.state()`` on a WSG reads natively (issue 20 §2): the driver's reader thread sends the five state
queries one after another by callback (drivers/wsg/callbacks.py), with no worker thread of the asyncio face
running it. Against the simulator over real transports (loopback TCP and UDP; a pty and a virtual CAN bus for
equality).

No wall-clock bound decides a test here: where "at once" matters, the connection's timeout is made long
(``TIMEOUT``) and the next call must end within half of it, which only an abandoned exchange allows (an
exchange left waiting holds its command's slot for the whole timeout).
"""

from __future__ import annotations

import asyncio
import dataclasses
import threading
from typing import Any

import pytest

import grippers.aio
from grippers import ConnectionLost, GripperState, GripperTimeout

TIMEOUT = 20.0

URLS = {
    "tcp": "sim://wsg50?transport=tcp&time_scale=10",
    "udp": "sim://wsg50?transport=udp&time_scale=10",
}
ALL_URLS = {
    **URLS,
    "pty": "sim://wsg50?transport=pty&time_scale=10",
    "can": "sim://wsg50?transport=can&time_scale=10",
}


def run(coro: Any) -> Any:
    return asyncio.run(asyncio.wait_for(coro, 120))


def same(a: GripperState, b: GripperState) -> bool:
    """Equal but for the moment each was taken."""
    return dataclasses.replace(a, timestamp=0.0) == dataclasses.replace(b, timestamp=0.0)


async def outstanding(g: grippers.aio.AsyncGripper) -> None:
    """Until a callback exchange of the native read is on the wire (bounded by the caller's wait_for)."""
    while not g.sync.driver.callbacks_waiting():
        await asyncio.sleep(0.001)


@pytest.mark.parametrize("name", list(ALL_URLS))
def test_native_state_equals_the_threaded_one(name: str) -> None:
    async def main() -> None:
        async with grippers.aio.open(ALL_URLS[name]) as g:
            await g.home()
            await g.move(0.04)
            awaited = await g.state()
            threaded = g.sync.state()
            assert same(awaited, threaded), (awaited, threaded)
            assert abs(awaited.width - 0.04) < 1e-3 and awaited.referenced and not awaited.moving

    run(main())


@pytest.mark.parametrize("name", list(URLS))
def test_state_needs_no_worker(name: str) -> None:
    """Every worker of the asyncio face is blocked, and state() still completes: no worker runs it."""

    async def main() -> None:
        async with grippers.aio.open(URLS[name]) as g:
            release = threading.Event()
            blocked = [g._workers.submit(lambda: release.wait(60)) for _ in range(grippers.aio.WORKERS)]
            try:
                st = await asyncio.wait_for(g.state(), TIMEOUT)
                assert st.width >= 0
                assert not any(f.done() for f in blocked)  # the workers were busy all along
            finally:
                release.set()
            await asyncio.gather(*blocked)

    run(main())


@pytest.mark.parametrize("name", list(URLS))
def test_100_concurrent_states_add_no_thread_and_share_the_line_with_threaded_ones(name: str) -> None:
    """Concurrent native reads queue for each command's slot (no thread each); a threaded caller reading
    the same commands meanwhile takes turns with them."""

    async def main() -> None:
        async with grippers.aio.open(URLS[name]) as g:
            await g.state()
            before = threading.enumerate()
            threaded: list[GripperState] = []
            errors: list[BaseException] = []

            def reads() -> None:
                try:
                    threaded.extend(g.sync.state() for _ in range(20))
                except BaseException as exc:  # noqa: BLE001 - asserted below
                    errors.append(exc)

            other = threading.Thread(target=reads)
            other.start()
            states = await asyncio.gather(*(g.state() for _ in range(100)))
            during = threading.enumerate()
            await asyncio.to_thread(other.join, 60)
            assert not errors, errors
            assert len(states) == 100 and len(threaded) == 20
            assert all(same(st, states[0]) for st in states + threaded)
            # (the threaded reader may have ended already)
            assert set(during) - set(before) <= {other}, [t.name for t in during]

    run(main())


@pytest.mark.parametrize("name", list(URLS))
def test_a_cancelled_state_leaves_the_connection_usable(name: str) -> None:
    """Cancelled while the device is silent: the exchange is abandoned (its late reply swallowed), and the
    next state(), awaited or threaded, goes out without waiting for the old exchange's timeout. Over TCP
    the next one proves the old reply lost with a LOOP at once; over UDP, which may reorder, only after
    ``stale_ttl`` (2 s), as after any abandoned exchange."""
    seen: list[dict[str, Any]] = []

    async def main() -> None:
        asyncio.get_running_loop().set_exception_handler(lambda _loop, context: seen.append(context))
        async with grippers.aio.open(URLS[name], timeout=TIMEOUT) as g:
            first = await g.state()
            faults = g.sync.simulator.faults
            for threaded_first in (True, False, True):  # again and again: nothing accumulates
                faults.silent = True
                with pytest.raises(asyncio.TimeoutError):
                    await asyncio.wait_for(g.state(), 0.01)
                faults.silent = False
                if threaded_first:
                    st = await asyncio.wait_for(asyncio.to_thread(g.sync.state), TIMEOUT / 2)
                    assert same(st, await asyncio.wait_for(g.state(), TIMEOUT / 2))
                else:
                    st = await asyncio.wait_for(g.state(), TIMEOUT / 2)
                    assert same(st, await asyncio.wait_for(asyncio.to_thread(g.sync.state), TIMEOUT / 2))
                assert same(st, first)
            # Once the device answered again, a reply that comes late was swallowed, never taken as another's.
            await asyncio.sleep(0.05)
            assert same(await g.state(), first)

    run(main())
    assert not seen, seen


def test_a_cancel_mid_read_abandons_the_exchange_out() -> None:
    """A cancel lands after some queries were answered: the one out is abandoned, no further one is sent."""

    async def main() -> None:
        async with grippers.aio.open(URLS["tcp"], timeout=TIMEOUT) as g:
            driver = g.sync.driver
            faults = g.sync.simulator.faults
            faults.drop_replies(1)  # only the first query's reply is lost: the read stops there
            task = asyncio.ensure_future(g.state())
            await asyncio.wait_for(outstanding(g), TIMEOUT)
            await asyncio.sleep(0.05)
            task.cancel()
            with pytest.raises(asyncio.CancelledError):
                await task
            assert not driver.callbacks_waiting()  # nothing left outstanding or queued
            assert (await asyncio.wait_for(g.state(), TIMEOUT / 2)).width >= 0

    run(main())


@pytest.mark.parametrize("name", list(URLS))
def test_a_timeout_is_the_threaded_calls_timeout(name: str) -> None:
    """The driver keeps the time of both faces: a silent device ends the read after one query's timeout,
    with the threaded call's words (the device's URL, the query's name)."""

    async def main() -> None:
        async with grippers.aio.open(URLS[name], timeout=0.2) as g:
            g.sync.simulator.faults.silent = True
            with pytest.raises(GripperTimeout) as caught:
                await asyncio.wait_for(g.state(), 10.0)
            with pytest.raises(GripperTimeout) as threaded:
                await asyncio.to_thread(g.sync.state)
            assert caught.value.device == threaded.value.device == g.sync.driver.device
            assert caught.value.command == threaded.value.command == "GET_SYSTEM_STATE (40h)"
            assert "within 0.2 s" in str(caught.value)
            g.sync.simulator.faults.silent = False
            # The timed-out read was abandoned: the gripper reads again (UDP: after stale_ttl).
            for _ in range(100):
                try:
                    assert (await g.state()).width >= 0
                    break
                except GripperTimeout:
                    continue
            else:
                pytest.fail("no state after the timeout")

    run(main())


def test_a_connection_lost_mid_read_raises_connection_lost() -> None:
    async def main() -> None:
        async with grippers.aio.open(URLS["tcp"], timeout=TIMEOUT) as g:
            faults = g.sync.simulator.faults
            faults.silent = True
            task = asyncio.ensure_future(g.state())
            await asyncio.wait_for(outstanding(g), TIMEOUT)
            faults.request_close()  # the server drops the TCP connection
            with pytest.raises(ConnectionLost) as caught:
                await asyncio.wait_for(task, TIMEOUT / 2)
            # Named as the threaded state() names it: the driver's device, and the query that was out.
            assert caught.value.device == g.sync.driver.device
            assert caught.value.command and caught.value.command.startswith("GET_")

    run(main())


@pytest.mark.parametrize("name", list(URLS))
def test_closing_the_driver_mid_read_raises_connection_lost(name: str) -> None:
    """The line closed under an outstanding read (UDP has no connection to lose): ConnectionLost, at once."""

    async def main() -> None:
        async with grippers.aio.open(URLS[name], timeout=TIMEOUT) as g:
            g.sync.simulator.faults.silent = True
            task = asyncio.ensure_future(g.state())
            await asyncio.wait_for(outstanding(g), TIMEOUT)
            await asyncio.to_thread(g.sync.driver.close, 0.1)
            with pytest.raises(ConnectionLost):
                await asyncio.wait_for(task, TIMEOUT / 2)
            with pytest.raises(ConnectionLost):  # a read started on a closed line fails at once
                await asyncio.wait_for(g.state(), TIMEOUT / 2)

    run(main())
