"""``await g.state()`` on an MSG over CAN is read natively (issue 20 §2): the poll (and frame 26 when the
status asks for the cause of an error) is a started request the bus reader completes, with no worker thread
(Device.start_read, StepfocBus.start_request). Over ``sim://msg-150`` (python-can ``virtual`` bus), a
``stepfoc+can://virtual/...`` URL to a simulator on its own channel, and python-can's ``udp_multicast`` bus,
which has a file descriptor, so the event loop reads it itself (drivers/stepfoc/can_reader.py): the same
outcomes whoever reads the bus.
"""

from __future__ import annotations

import asyncio
import dataclasses
import threading
import uuid
from collections.abc import Iterator
from typing import Any

import can
import pytest

import grippers.aio
from grippers.drivers.stepfoc.can_protocol import Cmd, unpack_id
from grippers.drivers.stepfoc.sim import MsgModel, serve_can
from grippers.errors import ConnectionLost, GripperTimeout, ProtocolError
from tests.mcast import private_port

TIMEOUT = 6.0  # long enough that "at once" and "after the old request's timeout" cannot be confused
NODE = 2


@dataclasses.dataclass
class Target:
    url: str
    server: Any  # the simulator server when the test started it (the URL case), else None

    def faults(self, g: grippers.aio.AsyncGripper) -> Any:
        return (self.server or g.sync.simulator).faults


def udp_multicast_bus() -> str:
    """A ``udp_multicast`` bus of this test's own (a private port isolates it: docs/protocols.md §2)."""
    pytest.importorskip("msgpack", reason="python-can's udp_multicast interface needs msgpack")
    return f"udp_multicast/{GROUP}?port={private_port()}"


GROUP = "239.74.163.2"  # python-can's IPv4 default group (administratively scoped)


@pytest.fixture(params=["sim", "url", "udp_multicast"])
def target(request: pytest.FixtureRequest) -> Iterator[Target]:
    if request.param == "sim":
        yield Target("sim://msg-150?transport=can&time_scale=20", None)
        return
    bus = f"virtual/aio-native-{uuid.uuid4().hex[:12]}" if request.param == "url" else udp_multicast_bus()
    server = serve_can([MsgModel(node=NODE)], f"can://{bus}", time_scale=20.0)
    sep = "&" if "?" in bus else "?"
    try:
        yield Target(f"stepfoc+can://{bus}{sep}node={NODE}&profile=msg-150", server)
    finally:
        server.close()
        assert server.error is None


def run(coro: Any) -> Any:
    return asyncio.run(asyncio.wait_for(coro, 120))


def spy_on(g: grippers.aio.AsyncGripper) -> can.BusABC:
    """Another program on the gripper's bus: sees every frame sent from now on."""
    bus = g.sync.driver.bus
    return can.Bus(**(bus._open_args or {"interface": "virtual", "channel": bus.channel}))


def frames(spy: can.BusABC, command: Cmd, remote: bool = False) -> int:
    """How many requests of ``command`` the spy has seen so far (takes them)."""
    count = 0
    while (msg := spy.recv(timeout=0)) is not None:
        count += unpack_id(msg.arbitration_id)[1] == command and msg.is_remote_frame == remote
    return count


def without_time(st: Any) -> Any:
    """The state but when it was read and the measured current (the simulator's has noise, as a motor's)."""
    assert st.current is not None  # measured over CAN, on both paths
    return dataclasses.replace(st, timestamp=0.0, current=None)


def test_100_concurrent_states_complete_with_every_worker_blocked(target: Target) -> None:
    """No worker thread is needed (all are blocked) and none is started: the reads are native."""

    async def main() -> None:
        async with grippers.aio.open(target.url, timeout=TIMEOUT) as g:
            await g.state()
            gate = threading.Event()
            blockers = [
                asyncio.ensure_future(g._call(lambda: gate.wait(60))) for _ in range(grippers.aio.WORKERS)
            ]
            try:
                threads = threading.active_count()
                states = await asyncio.wait_for(asyncio.gather(*(g.state() for _ in range(100))), 30)
                # none started (the bus's reader thread stays, watching, while the loop reads)
                assert threading.active_count() <= threads
            finally:
                gate.set()
                await asyncio.gather(*blockers)
            assert {without_time(s) for s in states} == {without_time(states[0])}

    run(main())


def test_native_states_equal_the_threaded_ones(target: Target) -> None:
    async def main() -> None:
        async with grippers.aio.open(target.url, timeout=TIMEOUT) as g:
            assert without_time(await g.state()) == without_time(g.sync.state())
            await g.home()
            await g.move(0.07)
            native, threaded = await g.state(), g.sync.state()
            assert without_time(native) == without_time(threaded)
            assert native.referenced and native.width == pytest.approx(0.07, abs=0.001)
            # the error bit set: both ask frame 26 for the cause (none named: "error")
            faults = target.faults(g)
            faults.error_bit_replies(1)
            native = await g.state()
            faults.error_bit_replies(1)
            threaded = g.sync.state()
            assert native.faults == threaded.faults == ("error",)
            assert without_time(native) == without_time(threaded)

    run(main())


def test_a_cancelled_state_frees_its_key_at_once(target: Target) -> None:
    async def main() -> None:
        async with grippers.aio.open(target.url, timeout=TIMEOUT) as g:
            bus = g.sync.driver.bus
            await g.state()
            faults = target.faults(g)
            for _ in range(3):  # again and again: nothing accumulates
                faults.silent = True
                with pytest.raises(asyncio.TimeoutError):
                    await asyncio.wait_for(g.state(), 0.01)
                assert not bus._waiters  # given up in the driver, not left to its timeout
                faults.silent = False
                assert (await asyncio.wait_for(g.state(), TIMEOUT / 2)).width >= 0

    run(main())


def test_a_state_cancelled_while_asking_for_the_error_cause_frees_that_key(target: Target) -> None:
    async def main() -> None:
        async with grippers.aio.open(target.url, timeout=TIMEOUT) as g:
            bus = g.sync.driver.bus
            await g.state()
            faults = target.faults(g)
            spy = spy_on(g)
            try:
                faults.error_bit_replies(1)  # the 60: frame 26 is asked for next...
                faults.drop_replies(1)  # ...and never answered
                with pytest.raises(asyncio.TimeoutError):
                    await asyncio.wait_for(g.state(), 1.0)
                assert frames(spy, Cmd.ERROR_STATE, remote=True) == 1
            finally:
                spy.shutdown()
                faults.clear()
            assert not bus._waiters
            assert (await asyncio.wait_for(g.state(), TIMEOUT / 2)).faults == ()

    run(main())


def test_no_reply_within_the_timeout_is_gripper_timeout(target: Target) -> None:
    async def main() -> None:
        async with grippers.aio.open(target.url, timeout=0.3) as g:
            faults = target.faults(g)
            faults.silent = True
            with pytest.raises(GripperTimeout, match="no reply within 0.3 s") as caught:
                await g.state()
            with pytest.raises(GripperTimeout) as threaded:
                await asyncio.to_thread(g.sync.state)
            # the bus keeps the time of both: one error, naming the node and its poll, whichever face asked
            assert (caught.value.device, caught.value.command, caught.value.message) == (
                threaded.value.device,
                threaded.value.command,
                threaded.value.message,
            )
            assert "node" in str(caught.value.device) and caught.value.command == "poll"
            faults.silent = False
            assert (await g.state()).width >= 0

    run(main())


def test_an_error_cause_never_answered_reads_as_the_threaded_call_reads_it(target: Target) -> None:
    """The poll says "error", frame 26 (its cause) never comes: both faces wait one request timeout for it
    and report the fault as "error" (no cause), not a timeout of the whole read."""

    async def main() -> None:
        async with grippers.aio.open(target.url, timeout=0.3) as g:
            await g.state()
            faults = target.faults(g)
            faults.error_bit_replies(1)
            faults.drop_replies(1)
            native = await asyncio.wait_for(g.state(), 5.0)
            faults.error_bit_replies(1)
            faults.drop_replies(1)
            threaded = await asyncio.to_thread(g.sync.state)
            assert native.faults == threaded.faults == ("error",)

    run(main())


def test_the_bus_closed_during_a_read_is_connection_lost(target: Target) -> None:
    async def main() -> None:
        async with grippers.aio.open(target.url, timeout=TIMEOUT) as g:
            bus = g.sync.driver.bus
            target.faults(g).silent = True
            read = asyncio.ensure_future(g.state())
            await asyncio.sleep(0)  # the poll is on the wire, waiting
            assert bus._waiters
            bus.close()
            with pytest.raises(ConnectionLost, match="CAN bus failed") as caught:
                await asyncio.wait_for(read, TIMEOUT / 2)
            assert "node" in str(caught.value.device) and caught.value.command == "poll"

    run(main())


def test_a_threaded_read_in_flight_keeps_its_reply(target: Target) -> None:
    """One request per (node, command) on the wire: the native poll queues behind the threaded one and goes
    out when it is answered; each gets its own reply."""

    async def main() -> None:
        async with grippers.aio.open(target.url, timeout=TIMEOUT) as g:
            await g.state()
            spy = spy_on(g)
            try:
                target.faults(g).delay_replies(0.5)
                first = asyncio.ensure_future(asyncio.to_thread(g.sync.state))
                poll = await asyncio.to_thread(spy.recv, TIMEOUT)  # the threaded poll went out
                assert poll is not None and unpack_id(poll.arbitration_id)[1] == Cmd.GRIPPER_COMMAND
                native = asyncio.ensure_future(g.state())
                await asyncio.sleep(0)  # started: queued behind it, not sent
                assert frames(spy, Cmd.GRIPPER_COMMAND) == 0
                assert not first.done()
                st = await asyncio.wait_for(native, TIMEOUT)
                assert without_time(st) == without_time(await first)
                assert frames(spy, Cmd.GRIPPER_COMMAND) == 1  # the native poll, once the threaded one ended
            finally:
                spy.shutdown()

    run(main())


@pytest.mark.parametrize("kind", ["virtual", "udp_multicast"])
def test_two_devices_on_one_node_id_fail_the_native_read_naming_the_node(kind: str) -> None:
    """Also over udp_multicast, which hands every frame back to its sender: our own polls coming back are
    not taken for another host's, which would give the twin's replies a request to answer (can_session.py)."""
    bus = f"virtual/aio-native-dup-{uuid.uuid4().hex[:8]}" if kind == "virtual" else udp_multicast_bus()
    a = serve_can([MsgModel(node=5)], f"can://{bus}", time_scale=20.0)
    b = None
    try:

        async def main() -> None:
            nonlocal b
            url = f"stepfoc+can://{bus}{'&' if '?' in bus else '?'}node=5&profile=msg-150"
            async with grippers.aio.open(url, timeout=TIMEOUT) as g:
                await g.state()
                b = serve_can([MsgModel(node=5, start_mm=10.0)], f"can://{bus}", time_scale=20.0)
                with pytest.raises(ProtocolError, match="two devices answer as node 5"):
                    for _ in range(50):
                        await g.state()
                        await asyncio.sleep(0.01)
                with pytest.raises(ProtocolError, match="two devices answer as node 5"):
                    await g.state()  # from now on, every read

        run(main())
    finally:
        a.close()
        if b is not None:
            b.close()
