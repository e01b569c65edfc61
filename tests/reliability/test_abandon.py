"""The drivers' ``abandon(thread)`` hook (issue 23 §3): a caller that stops waiting from another thread
(grippers.aio when the awaiting task is cancelled) frees the connection at once, on a real transport to a
simulator that went silent and then answers again.

Each test runs the given-up call on a thread of its own, gives it up from the test thread and checks that
(1) the call ends with "abandoned" long before its own timeout, (2) the next call of the same command
succeeds well within its timeout once the device answers, (3) the thread is usable again after ``resume``.
"""

from __future__ import annotations

import threading
import time
from collections.abc import Callable
from typing import Any

import pytest

from grippers.drivers.errors import GripperTimeout
from grippers.drivers.stepfoc.can_client import StepfocBus
from grippers.drivers.stepfoc.sim import MsgModel
from grippers.drivers.stepfoc.uart_client import StepfocUart

TIMEOUT = 6.0  # the given-up call's own timeout: "at once" means well under half of it, on a busy machine


class _Caller:
    """Runs ``fn`` on a thread of its own; ``ident`` once it runs, ``outcome`` once it ended."""

    def __init__(self, fn: Callable[[], Any]) -> None:
        self.outcome: BaseException | object = None
        self.ended_after: float | None = None
        self._fn = fn
        self._started = threading.Event()
        self.thread = threading.Thread(target=self._run, daemon=True)
        self.thread.start()
        assert self._started.wait(5.0)
        self.ident = self.thread.ident
        assert self.ident is not None

    def _run(self) -> None:
        began = time.monotonic()
        self._started.set()
        try:
            self.outcome = self._fn()
        except BaseException as exc:  # noqa: BLE001 - inspected by the test
            self.outcome = exc
        self.ended_after = time.monotonic() - began

    def join(self) -> None:
        self.thread.join(TIMEOUT + 5.0)
        assert not self.thread.is_alive()


def _given_up_at_once(caller: _Caller) -> None:
    caller.join()
    assert isinstance(caller.outcome, GripperTimeout), caller.outcome
    assert "abandoned" in str(caller.outcome)
    assert caller.ended_after is not None and caller.ended_after < TIMEOUT / 2


def _until_outstanding(c: Any, cmd: int) -> None:
    """Until the client has sent its request of ``cmd`` (its session holds the exchange), so the give-up
    below meets an exchange on the wire on any machine, not a caller still on its way to the send."""
    deadline = time.monotonic() + 5.0
    while cmd not in c.outstanding():
        assert time.monotonic() < deadline, "the request never went out"
        time.sleep(0.005)


# ------------------------------------------------------------------------------------------------- WSG


@pytest.mark.parametrize("transport", ["tcp", "udp"])
def test_wsg_abandoned_query_frees_its_command(wsg_sim, wsg_connect, transport: str) -> None:
    """TCP keeps replies in order: the next request of the id proves the abandoned reply lost with one
    LOOP barrier at once, however long ``stale_ttl`` is. UDP may reorder datagrams: the margin stays."""
    server = wsg_sim(f"{transport}://127.0.0.1:0")
    c = wsg_connect(server.url, timeout=TIMEOUT, stale_ttl=60.0)
    assert c.width() >= 0
    server.faults.silent = True
    caller = _Caller(c.width)
    _until_outstanding(c, 0x43)  # GET_WIDTH: a silent simulator reads it and answers nothing
    c.abandon(caller.ident)
    _given_up_at_once(caller)
    server.faults.silent = False
    if transport == "udp":
        with pytest.raises(GripperTimeout, match="still outstanding"):
            c.width(timeout=0.3)
        assert c.loop(b"other ids work") == b"other ids work"
        return
    began = time.monotonic()
    assert c.width() == pytest.approx(server.model.width(), abs=0.01)
    assert time.monotonic() - began < TIMEOUT / 2
    assert c.stats["barriers"] == 1 and c.stats["lost_replies"] == 1
    c.resume(caller.ident)
    again = _Caller(c.width)  # a fresh thread: the set of given-up threads does not leak into others
    again.join()
    assert isinstance(again.outcome, float)


def test_wsg_abandon_of_a_thread_that_waits_for_nothing_changes_nothing(wsg_sim, wsg_connect) -> None:
    server = wsg_sim()
    c = wsg_connect(server.url, timeout=TIMEOUT)
    c.abandon(threading.get_ident())
    with pytest.raises(GripperTimeout, match="abandoned"):
        c.width()  # given up until resume: nothing is sent for a caller that is gone
    c.resume(threading.get_ident())
    assert c.width() == pytest.approx(server.model.width(), abs=0.01)
    assert c.stats["barriers"] == 0 and c.stats["stale_replies"] == 0


# ------------------------------------------------------------------------------------------------- MSG


def _abandoned_read_frees_the_link(server: Any, handle: Any, read: Callable[[], int]) -> None:
    """A caller of ``read`` (a position) waiting on the silent simulator is given up and leaves at once; once
    the simulator answers again, the next ``read`` goes out at once (half the timeout: nothing waited)."""
    assert read() >= 0
    server.faults.silent = True
    caller = _Caller(read)
    time.sleep(0.1)
    handle.abandon(caller.ident)
    _given_up_at_once(caller)
    server.faults.silent = False
    began = time.monotonic()
    assert read() >= 0
    assert time.monotonic() - began < TIMEOUT / 2
    handle.resume(caller.ident)


def test_msg_can_abandoned_poll_frees_its_key(msg_can_sim, can_channel) -> None:
    server = msg_can_sim(MsgModel(node=5))
    with StepfocBus(interface="virtual", channel=can_channel) as bus:
        n = bus.node(5, timeout=TIMEOUT)
        # the (node, 61) key is free afterwards: no "another poll ... did not finish"
        _abandoned_read_frees_the_link(server, n, lambda: n.poll().position)


def test_msg_can_abandon_reaches_a_caller_waiting_for_the_key(msg_can_sim, can_channel) -> None:
    """Two threads poll one node; the one queued behind the other's exchange is given up: it leaves at
    once instead of waiting for the key, and the first one's exchange is untouched."""
    server = msg_can_sim(MsgModel(node=6))
    with StepfocBus(interface="virtual", channel=can_channel) as bus:
        n = bus.node(6, timeout=TIMEOUT)
        server.faults.silent = True
        first = _Caller(n.poll)
        time.sleep(0.1)
        second = _Caller(n.poll)
        time.sleep(0.1)
        n.abandon(second.ident)
        _given_up_at_once(second)
        assert first.thread.is_alive()  # still waiting for its own reply
        server.faults.silent = False
        n.abandon(first.ident)
        _given_up_at_once(first)


def test_msg_uart_abandoned_exchange_frees_the_port(msg_uart_sim) -> None:
    server = msg_uart_sim()
    with StepfocUart(server.url, timeout=TIMEOUT) as u:
        _abandoned_read_frees_the_link(server, u, u.position)
