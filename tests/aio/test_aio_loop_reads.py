"""An MSG on a CAN bus with a file descriptor is read by the event loop itself while an asyncio face is open
on it and its loop runs (drivers/stepfoc/can_reader.py): the reader thread only watches then, and the threaded
calls under the face (motions on workers, a blocking call made on the loop's own thread, a face whose loop
ended unclosed) still get their replies, and so do the other users of the bus while that loop blocks, idles
or has ended (issue 33 §2). python-can's ``udp_multicast`` bus (a UDP socket) stands in for SocketCAN here;
tests/vcan runs the same on a real SocketCAN interface.
"""

from __future__ import annotations

import asyncio
import threading
import time
import uuid
from collections.abc import Iterator
from typing import Any

import pytest

import grippers.aio
from grippers.drivers import canlink
from grippers.drivers.stepfoc.device import CanLink
from grippers.drivers.stepfoc.sim import MsgModel, serve_can
from tests.aio.test_aio_state_native_msg import NODE, udp_multicast_bus, without_time

pytestmark = pytest.mark.udp_multicast
TIMEOUT = 6.0


def readers(url_bus: str) -> list[threading.Thread]:
    """The bus's reader threads alive now (named after the bus: drivers/stepfoc/can_reader.py)."""
    name = f"stepfoc-can stepfoc+can://{url_bus.split('?')[0]}"
    return [t for t in threading.enumerate() if t.name == name]


def loop_reads(g: grippers.aio.AsyncGripper) -> bool:
    """The event loop holds the gripper's bus (the reader thread only watches)."""
    return bool(g.sync.driver.bus._reader.loop_reads)


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
            await until(lambda: loop_reads(g), "the reader thread handed over to the loop")
            native = await g.state()
            threaded = await asyncio.to_thread(g.sync.state)  # a worker waits; the loop reads its reply
            assert without_time(native) == without_time(threaded)
            assert loop_reads(g) and len(readers(bus)) == 1  # the thread watches

    run(main())


def test_read_on_loop_false_keeps_the_reader_thread(sim: tuple[str, Any]) -> None:
    bus, _ = sim

    async def main() -> None:
        async with grippers.aio.open(url(bus), timeout=TIMEOUT, read_on_loop=False) as g:
            await g.state()
            await asyncio.sleep(0.2)  # four reader poll periods: a hand-over would have happened
            assert len(readers(bus)) == 1 and not loop_reads(g)

    run(main())


def test_the_loop_reads_the_in_process_virtual_bus() -> None:
    """``sim://msg-150``'s python-can ``virtual`` bus, as the library opens it, has a descriptor
    (drivers/virtual_can.py, issue 43 §8): the loop reads it, concurrent awaits and a motion on a worker are
    all answered, and the bus goes back to the thread when the face closes."""

    async def main() -> None:
        async with grippers.aio.open("sim://msg-150", timeout=TIMEOUT) as g:
            await until(lambda: loop_reads(g), "the reader thread handed over to the loop")
            native = await g.state()
            threaded = await asyncio.to_thread(g.sync.state)  # a worker waits; the loop reads its reply
            assert without_time(native) == without_time(threaded)
            assert g.sync.state().width >= 0  # a blocking call on the loop's own thread reads the bus itself
            states = await asyncio.gather(*(g.state() for _ in range(50)))
            assert len(states) == 50 and all(st.width >= 0 for st in states)
            await g.home()
            moved = await g.move(0.05)
            assert abs(moved.width - 0.05) < 0.002 and abs((await g.state()).width - 0.05) < 0.002
            assert loop_reads(g)
            sync = g.sync
        assert not sync.driver.bus._reader.loop_reads

    run(main())


def test_a_bus_without_a_file_descriptor_keeps_its_reader_thread(monkeypatch: pytest.MonkeyPatch) -> None:
    """A platform without ``eventfd`` opens python-can's own ``virtual`` bus, which has no descriptor."""
    monkeypatch.setattr(canlink, "waitable", lambda: False)
    channel = f"aio-loop-virtual-{uuid.uuid4().hex[:8]}"
    server = serve_can([MsgModel(node=NODE)], f"can://virtual/{channel}", time_scale=20.0)

    async def main() -> None:
        async with grippers.aio.open(
            f"stepfoc+can://virtual/{channel}?node={NODE}&profile=msg-150", timeout=TIMEOUT
        ) as g:
            assert g.sync.async_support().read_on(asyncio.get_running_loop()) is None
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
            await until(lambda: loop_reads(g), "the hand-over")
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
            await until(lambda: loop_reads(g), "the hand-over")
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
        await until(lambda: loop_reads(b), "the hand-over")
        await a.close()
        assert (await b.state()).width >= 0
        assert loop_reads(b)
        await b.close()
        assert not readers(bus)
        assert not [key for key in CanLink.shared_buses() if key[0] == "udp_multicast" and bus in f"{key[1]}"]

    run(main())


def test_a_threaded_gripper_under_a_loop_that_ended_unclosed_reads_again(sim: tuple[str, Any]) -> None:
    """The program forgot ``close()`` and its loop ended: the bus goes back to a reader thread on the next
    request instead of every threaded call timing out."""
    bus, _ = sim

    async def main() -> grippers.aio.AsyncGripper:
        g = await grippers.aio.open(url(bus), timeout=TIMEOUT)
        await until(lambda: loop_reads(g), "the hand-over")
        await g.state()
        return g

    g = run(main())
    try:
        assert g.sync.state().width >= 0
        assert len(readers(bus)) == 1 and not loop_reads(g)
    finally:
        g.sync.close()
    assert not readers(bus)


def test_a_silent_node_times_out_on_the_loops_clock(sim: tuple[str, Any]) -> None:
    bus, server = sim

    async def main() -> None:
        async with grippers.aio.open(url(bus), timeout=0.3) as g:
            await until(lambda: loop_reads(g), "the hand-over")
            server.faults.silent = True
            with pytest.raises(grippers.GripperTimeout, match="no reply within 0.3 s"):
                await asyncio.wait_for(g.state(), 5.0)
            server.faults.silent = False
            assert (await g.state()).width >= 0

    run(main())


# ---------------------------------------------------------------------------------------------------------
# One user's loop is nobody else's single point of failure (issue 33 §2): the bus is shared by every user
# in the process, so a loop that ended, blocks or idles gives the bus back to the reader thread.

STALL_BOUND_S = 0.5  # the other users' timeout: the thread takes over well within it (STALL_S = 0.2 s)


def in_thread(body: Any) -> tuple[threading.Thread, list[BaseException]]:
    errors: list[BaseException] = []

    def run_it() -> None:
        try:
            body()
        except BaseException as exc:  # handed to the test
            errors.append(exc)

    t = threading.Thread(target=run_it, daemon=True)
    t.start()
    return t, errors


def test_a_loop_that_ended_unclosed_leaves_another_loops_native_read_answered(sim: tuple[str, Any]) -> None:
    """Two loops in two threads on one bus: loop A reads it and ends without close(); loop B's native read
    (whose time the bus's reader keeps) is answered, or at worst times out, within its deadline."""
    bus, _ = sim
    a_reads, b_opened = threading.Event(), threading.Event()
    left_open: list[grippers.aio.AsyncGripper] = []

    def loop_a() -> None:
        async def main() -> None:
            g = await grippers.aio.open(url(bus, NODE), timeout=TIMEOUT)
            left_open.append(g)
            await until(lambda: loop_reads(g), "loop A holds the bus")
            a_reads.set()
            await asyncio.to_thread(b_opened.wait, 30)  # ... and A ends here, its gripper open

        run(main())

    async def loop_b() -> float:
        a, errors = in_thread(loop_a)
        await asyncio.to_thread(a_reads.wait, 30)
        g1 = await grippers.aio.open(url(bus, NODE + 1), timeout=STALL_BOUND_S)  # A reads the bus, not B
        try:
            b_opened.set()
            await asyncio.to_thread(a.join, 30)
            assert a_reads.is_set() and not errors and not a.is_alive()
            start = asyncio.get_running_loop().time()
            state = await asyncio.wait_for(g1.state(), 5.0)  # was: still pending after 5 s
            assert state.width >= 0
            return asyncio.get_running_loop().time() - start
        finally:
            await g1.close()

    try:
        took = run(loop_b())
    finally:
        for g in left_open:
            g.sync.close()
    assert took < 2 * STALL_BOUND_S  # within the read's own deadline (a poll, then maybe frame 26)


def test_a_native_read_has_a_deadline_of_its_own_when_nobody_reads_the_bus(sim: tuple[str, Any]) -> None:
    """The last line of defence: even when nothing reads the bus (its reader stopped here, as a stalled one
    would), an awaited native read ends with GripperTimeout at its own deadline (two exchanges and slack)
    instead of pending for ever: the bus's clock, which keeps a native read's time, runs on that reader."""
    bus, _ = sim

    async def main() -> None:
        async with grippers.aio.open(url(bus, NODE), timeout=0.3, read_on_loop=False) as g:
            reader = g.sync.driver.bus._reader
            reader._thread_stop.set()  # nobody reads, nobody ticks
            reader._thread.join(5)
            loop = asyncio.get_running_loop()
            start = loop.time()
            with pytest.raises(grippers.GripperTimeout, match="no reply within 0.85 s"):
                await asyncio.wait_for(g.state(), 5.0)  # was: still pending after 5 s
            assert loop.time() - start < 2.0

    run(main())


def threaded_states(bus: str, count: int, period: float) -> list[float]:
    """A threaded gripper on another node of the bus polls ``count`` times; the widths it read."""
    with grippers.open(url(bus, NODE + 1), timeout=STALL_BOUND_S) as g:
        widths = []
        for _ in range(count):
            widths.append(g.state().width)
            time.sleep(period)
        return widths


def test_a_blocked_loop_does_not_starve_a_threaded_gripper_on_the_same_bus(sim: tuple[str, Any]) -> None:
    bus, _ = sim
    blocking = threading.Event()
    done = threading.Event()

    def loop_a() -> None:
        async def main() -> None:
            async with grippers.aio.open(url(bus, NODE), timeout=TIMEOUT) as g:
                await until(lambda: loop_reads(g), "loop A holds the bus")
                blocking.set()
                done.wait(20)  # a blocking call on the loop's thread: the loop reads nothing meanwhile
                assert (await g.state()).width >= 0  # and it reads again afterwards
                await until(lambda: loop_reads(g), "the bus handed back to loop A")

        run(main())

    a, errors = in_thread(loop_a)
    try:
        assert blocking.wait(30)
        assert len(threaded_states(bus, 6, 0.1)) == 6  # each within 0.5 s: was GripperTimeout
    finally:
        done.set()
        a.join(30)
    assert not errors


def test_an_idle_loop_does_not_starve_a_threaded_gripper_on_the_same_bus(sim: tuple[str, Any]) -> None:
    """Opened with run_until_complete, then the loop does not run: the bus is read all the same, by the
    thread, and the loop takes it again when it runs."""
    bus, _ = sim
    loop = asyncio.new_event_loop()
    try:
        g = loop.run_until_complete(grippers.aio.open(url(bus, NODE), timeout=TIMEOUT))
        try:
            assert loop.run_until_complete(g.state()).width >= 0  # the loop ran a while: it may hold the bus
            polled: list[float] = []
            other, errors = in_thread(lambda: polled.extend(threaded_states(bus, 4, 0.1)))
            other.join(30)  # another thread's user; the loop idles meanwhile
            assert not errors and len(polled) == 4  # each within 0.5 s: was GripperTimeout
            assert not loop_reads(g)  # taken back
            assert loop.run_until_complete(g.state()).width >= 0

            async def handed_back() -> None:
                await until(lambda: loop_reads(g), "the bus handed back to the running loop")

            loop.run_until_complete(handed_back())
        finally:
            loop.run_until_complete(g.close())
    finally:
        loop.close()
    assert not readers(bus)
