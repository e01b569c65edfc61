"""An MSG on a CAN bus with a file descriptor is read by the event loop itself while an asyncio face is open
on it (drivers/stepfoc/can_reader.py): no reader thread then, and the threaded calls under the face (motions
on workers, a blocking call made on the loop's own thread, a face whose loop ended unclosed) still get their
replies. python-can's ``udp_multicast`` bus (a UDP socket) stands in for SocketCAN here; tests/vcan runs the
same on a real SocketCAN interface.
"""

from __future__ import annotations

import asyncio
import threading
import uuid
from collections.abc import Iterator
from typing import Any

import pytest

import grippers.aio
from grippers.backends.stepfoc import _CanLink
from grippers.drivers.stepfoc.sim import MsgModel, serve_can
from tests.aio.test_aio_state_native_msg import NODE, udp_multicast_bus, without_time

pytestmark = pytest.mark.udp_multicast
TIMEOUT = 6.0


def readers(url_bus: str) -> list[threading.Thread]:
    """The bus's reader threads alive now (named after the bus: drivers/stepfoc/can_reader.py)."""
    name = f"stepfoc-can stepfoc+can://{url_bus.split('?')[0]}"
    return [t for t in threading.enumerate() if t.name == name]


@pytest.fixture
def sim() -> Iterator[tuple[str, Any]]:
    """(bus, server): MSG nodes NODE and NODE + 1 on a udp_multicast bus of this test's own."""
    bus = udp_multicast_bus()
    server = serve_can([MsgModel(node=NODE), MsgModel(node=NODE + 1)], f"can://{bus}", time_scale=20.0)
    try:
        yield bus, server
    finally:
        server.close()
        assert server.error is None


def url(bus: str, node: int = NODE) -> str:
    return f"stepfoc+can://{bus}&node={node}&profile=msg-150"


def run(coro: Any) -> Any:
    return asyncio.run(asyncio.wait_for(coro, 120))


async def until(predicate: Any, what: str) -> None:
    """The reader thread hands over within its poll period (50 ms); wait for it, bounded."""
    for _ in range(200):
        if predicate():
            return
        await asyncio.sleep(0.01)
    raise AssertionError(f"not within 2 s: {what}")


def test_the_loop_reads_the_bus_and_both_faces_read_the_same_state(sim: tuple[str, Any]) -> None:
    bus, _ = sim

    async def main() -> None:
        async with grippers.aio.open(url(bus), timeout=TIMEOUT) as g:
            await until(lambda: not readers(bus), "the reader thread handed over to the loop")
            native = await g.state()
            threaded = await asyncio.to_thread(g.sync.state)  # a worker waits; the loop reads its reply
            assert without_time(native) == without_time(threaded)
            assert not readers(bus)

    run(main())


def test_read_on_loop_false_keeps_the_reader_thread(sim: tuple[str, Any]) -> None:
    bus, _ = sim

    async def main() -> None:
        async with grippers.aio.open(url(bus), timeout=TIMEOUT, read_on_loop=False) as g:
            await g.state()
            await asyncio.sleep(0.2)  # four reader poll periods: a hand-over would have happened
            assert len(readers(bus)) == 1

    run(main())


def test_a_bus_without_a_file_descriptor_keeps_its_reader_thread() -> None:
    channel = f"aio-loop-virtual-{uuid.uuid4().hex[:8]}"
    server = serve_can([MsgModel(node=NODE)], f"can://virtual/{channel}", time_scale=20.0)

    async def main() -> None:
        async with grippers.aio.open(
            f"stepfoc+can://virtual/{channel}?node={NODE}&profile=msg-150", timeout=TIMEOUT
        ) as g:
            assert g.sync._read_on(asyncio.get_running_loop()) is None
            await g.state()
            assert len(readers(f"virtual/{channel}")) == 1

    try:
        run(main())
    finally:
        server.close()


def test_motions_run_on_workers_while_the_loop_reads(sim: tuple[str, Any]) -> None:
    bus, _ = sim

    async def main() -> None:
        async with grippers.aio.open(url(bus), timeout=TIMEOUT) as g:
            await until(lambda: not readers(bus), "the hand-over")
            await g.home()
            moved = await g.move(0.05)
            assert abs(moved.width - 0.05) < 0.002 and abs((await g.state()).width - 0.05) < 0.002

    run(main())


def test_a_blocking_call_on_the_loops_own_thread_is_answered(sim: tuple[str, Any]) -> None:
    """The loop cannot read while a coroutine blocks it: the blocked request reads the bus itself, whether
    the reader thread is still handing over (right after open) or the loop reads already."""
    bus, _ = sim

    async def main() -> None:
        async with grippers.aio.open(url(bus), timeout=TIMEOUT) as g:
            assert g.sync.state().width >= 0  # at once: the hand-over is on its way
            await until(lambda: not readers(bus), "the hand-over")
            assert g.sync.state().width >= 0
            assert (await g.state()).width >= 0  # and the loop still reads afterwards

    run(main())


def test_closing_gives_the_bus_back_then_releases_it(sim: tuple[str, Any]) -> None:
    """Two grippers on one bus share its reader: closing one leaves the loop reading for the other; closing
    both closes the bus and leaves no thread."""
    bus, _ = sim

    async def main() -> None:
        a = await grippers.aio.open(url(bus, NODE), timeout=TIMEOUT)
        b = await grippers.aio.open(url(bus, NODE + 1), timeout=TIMEOUT)
        await until(lambda: not readers(bus), "the hand-over")
        await a.close()
        assert (await b.state()).width >= 0
        assert not readers(bus)
        await b.close()
        assert not readers(bus)
        assert not [key for key in _CanLink._buses if key[0] == "udp_multicast" and bus in f"{key[1]}"]

    run(main())


def test_a_threaded_gripper_under_a_loop_that_ended_unclosed_reads_again(sim: tuple[str, Any]) -> None:
    """The program forgot ``close()`` and its loop ended: the bus goes back to a reader thread on the next
    request instead of every threaded call timing out."""
    bus, _ = sim

    async def main() -> grippers.aio.AsyncGripper:
        g = await grippers.aio.open(url(bus), timeout=TIMEOUT)
        await until(lambda: not readers(bus), "the hand-over")
        await g.state()
        return g

    g = run(main())
    try:
        assert g.sync.state().width >= 0
        assert len(readers(bus)) == 1
    finally:
        g.sync.close()
    assert not readers(bus)


def test_a_silent_node_times_out_on_the_loops_clock(sim: tuple[str, Any]) -> None:
    bus, server = sim

    async def main() -> None:
        async with grippers.aio.open(url(bus), timeout=0.3) as g:
            await until(lambda: not readers(bus), "the hand-over")
            server.faults.silent = True
            with pytest.raises(grippers.GripperTimeout, match="no reply within 0.3 s"):
                await asyncio.wait_for(g.state(), 5.0)
            server.faults.silent = False
            assert (await g.state()).width >= 0

    run(main())
