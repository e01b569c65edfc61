"""Eight threads x 1,000 mixed commands plus two state streams on ONE connection: one WSG over loopback TCP,
one CAN bus with four MSG nodes. Every reply must reach its caller (the values say which request they answer),
nothing may deadlock (bounded joins), queues stay bounded, and close() leaves no thread or descriptor."""

from __future__ import annotations

import threading
import time
from collections.abc import Callable

import pytest

from grippers.drivers.errors import GripperTimeout
from grippers.drivers.stepfoc.can_client import StepfocBus
from grippers.drivers.stepfoc.sim import MsgModel, serve_can
from grippers.drivers.wsg.client import WsgClient
from grippers.drivers.wsg.commands import Cmd, GraspingState, SystemFlags
from grippers.drivers.wsg.sim import WsgModel, serve

THREADS = 8
COMMANDS_PER_THREAD = 1000
JOIN_S = 60.0  # far above the expected run time: a join that times out is a deadlock


def _run_workers(work: Callable[[int], None], streams: list[Callable[[threading.Event], None]]) -> None:
    errors: list[BaseException] = []
    stop = threading.Event()

    def guard(fn: Callable[..., None], *args: object) -> None:
        try:
            fn(*args)
        except BaseException as exc:  # collected and re-raised in the test thread
            errors.append(exc)

    stream_threads = [threading.Thread(target=guard, args=(s, stop), daemon=True) for s in streams]
    workers = [threading.Thread(target=guard, args=(work, i), daemon=True) for i in range(THREADS)]
    for t in stream_threads + workers:
        t.start()
    deadline = time.monotonic() + JOIN_S
    for t in workers:
        t.join(max(0.0, deadline - time.monotonic()))
    stop.set()
    for t in stream_threads:
        t.join(5.0)
    stuck = [t.name for t in workers + stream_threads if t.is_alive()]
    assert not stuck, f"deadlock: {stuck} still running"
    if errors:
        raise errors[0]


def test_wsg_eight_threads_and_two_subscriptions_on_one_connection(snapshot) -> None:
    before = snapshot()
    model = WsgModel(serial=424242, stroke_mm=110.0)
    server = serve(model, "tcp://127.0.0.1:0", time_scale=1.0)
    client = WsgClient.from_url(server.url, timeout=5.0)
    client.home(timeout=10.0)
    widths = client.subscribe(Cmd.GET_WIDTH, period_ms=10, maxsize=32)
    flags = client.subscribe(Cmd.GET_SYSTEM_STATE, period_ms=10, maxsize=16)  # never read until the end
    consumed = []

    def stream(stop: threading.Event) -> None:
        while not stop.is_set():
            try:
                consumed.append(widths.get(timeout=1.0))
            except GripperTimeout:
                pass

    def work(i: int) -> None:
        for k in range(COMMANDS_PER_THREAD):
            op = (i + k) % 6
            if op == 0:
                tag = f"{i}:{k}".encode()
                assert client.loop(tag) == tag  # the echo proves the reply is this request's
            elif op == 1:
                assert client.system_info().serial == 424242
            elif op == 2:
                assert client.system_limits().stroke == pytest.approx(110.0)
            elif op == 3:
                assert 0.0 <= client.width() <= 110.0
            elif op == 4:
                assert SystemFlags.SF_REFERENCED in client.system_state()
            else:
                assert client.grasping_state() in set(GraspingState)

    _run_workers(work, [stream])
    assert len(consumed) > 0 and all(0.0 <= w <= 110.0 for w in consumed)
    drained = 0
    while True:
        try:
            flags.get(timeout=0)
            drained += 1
        except GripperTimeout:
            break
    assert drained <= 16 and drained == flags.received - flags.dropped  # bounded: the oldest were dropped
    assert client.stats["checksum_errors"] == client.stats["unsolicited"] == 0
    client.close()
    server.close()
    assert server.error is None
    threads, fds = before.leaks()
    assert not threads and not fds, (threads, fds)


def test_can_eight_threads_four_nodes_and_two_streams_on_one_bus(snapshot, can_channel) -> None:
    before = snapshot()
    models = [
        MsgModel(node=n, serial=5000 + n, temperature_c=30 + n, bus_voltage_mv=24000 + n) for n in range(4)
    ]
    server = serve_can(models, f"can://virtual/{can_channel}", time_scale=200.0)
    bus = StepfocBus(interface="virtual", channel=can_channel)
    nodes = [bus.node(n, timeout=5.0, current_limit_ma=900) for n in range(4)]
    streamed = [0, 0]

    def stream(n: int) -> Callable[[threading.Event], None]:
        def run(stop: threading.Event) -> None:
            while not stop.is_set():
                assert 0 <= nodes[n].poll().position <= 255
                streamed[n - 2] += 1

        return run

    def work(i: int) -> None:
        node = nodes[i % 4]
        n = node.node
        for k in range(COMMANDS_PER_THREAD):
            op = (i + k) % 5
            if op == 0:
                assert node.device_info().serial == 5000 + n  # a reply from node n, to this caller
            elif op == 1:
                assert node.temperature() == 30 + n
            elif op == 2:
                assert node.bus_voltage() == 24000 + n
            elif op == 3:
                st = node.command(k % 256, 100, 2000, action=False)  # current clamped to 900 before sending
                assert 0 <= st.position <= 255
            else:
                assert node.poll().current_ma is not None

    _run_workers(work, [stream(2), stream(3)])
    assert min(streamed) > 0
    for m in models:
        assert m.current_setpoint == 900  # the clamp held under contention
    assert not bus._waiters  # every waiter was removed: nothing grows with the number of requests
    bus.close()
    server.close()
    assert server.error is None
    threads, fds = before.leaks()
    assert not threads and not fds, (threads, fds)


@pytest.mark.parametrize(
    "url",
    [
        "sim://wsg50?time_scale=50",
        "sim://wsg50?time_scale=50&transport=udp",
        "sim://wsg50?time_scale=50&transport=pty",
        "sim://wsg50?time_scale=50&transport=can",
        "sim://msg-150?time_scale=200",
        "sim://msg-150?time_scale=200&transport=pty",
    ],
)
def test_api_close_leaves_no_thread_or_descriptor(snapshot, url: str) -> None:
    """A gripper used from several threads at once (a motion, a stream, state reads), then closed."""
    import grippers

    before = snapshot()
    g = grippers.open(url)
    g.home()
    stream = g.stream(rate_hz=50)
    handle = g.move(g.limits.max_width * 0.5, wait=False)
    readers = [threading.Thread(target=lambda: [g.state() for _ in range(20)]) for _ in range(3)]
    for t in readers:
        t.start()
    for t in readers:
        t.join(20.0)
    assert stream.get(timeout=5.0) is not None
    handle.wait(20.0)
    g.close()  # closes the stream and the simulator too
    threads, fds = before.leaks()
    assert not threads and not fds, (threads, fds)


@pytest.mark.parametrize("url", ["sim://wsg50?time_scale=50", "sim://msg-150?time_scale=200"])
def test_api_racing_motions_and_stops_each_end_honestly(snapshot, url: str) -> None:
    """Eight threads start motions, stop and cancel them at random on one gripper (issue 12 §3): every
    motion ends with its own result or CommandFailed "superseded"/"aborted", none hangs, none returns the
    result of another motion, and the gripper is usable and leak-free afterwards."""
    import random

    import grippers
    from grippers import CommandFailed, GripperTimeout
    from grippers.motions import MotionHandle

    before = snapshot()
    g = grippers.open(url)
    g.home()
    lo, hi = g.limits.min_width, g.limits.max_width
    outcomes: dict[str, int] = {"own result": 0, "superseded": 0, "aborted": 0}
    lock = threading.Lock()

    def count(kind: str) -> None:
        with lock:
            outcomes[kind] += 1

    def work(i: int) -> None:
        rng = random.Random(i)
        for _ in range(25):
            target = round(rng.uniform(lo + 0.005, hi - 0.005), 3)
            roll = rng.random()
            try:
                if roll < 0.15:
                    g.stop()
                    continue
                handle = g.move(target, wait=False)
                assert isinstance(handle, MotionHandle)
                if roll < 0.3:
                    handle.cancel()
                result = handle.wait(30.0)
                # Its own result: the width it was sent to (a motion that returns has reached its target).
                assert result.width == pytest.approx(target, abs=0.003), (target, result)
                count("own result")
            except CommandFailed as exc:
                text = str(exc)
                kind = "superseded" if "superseded by" in text else "aborted" if "aborted by" in text else ""
                assert kind, exc
                count(kind)
            except GripperTimeout as exc:  # a wait(30) that runs out is a hang
                raise AssertionError(f"a motion hung: {exc}") from exc

    _run_workers(work, [])
    assert sum(outcomes.values()) > 100 and outcomes["superseded"] and outcomes["aborted"], outcomes
    assert g.move((lo + hi) / 2).width == pytest.approx((lo + hi) / 2, abs=0.003)
    g.close()
    threads, fds = before.leaks()
    assert not threads and not fds, (threads, fds)
