"""Issue 23 §3: Ctrl-C at every line of a WSG exchange leaves the client usable and the gripper stoppable.

A KeyboardInterrupt is delivered where the main thread next checks for signals, which may be inside the
wait for a lock or for a reply (CI once failed with ``RuntimeError: cannot release un-acquired lock`` from
the client's wait).
Random timers hit such windows rarely; here a trace function raises KeyboardInterrupt at the first signal
delivery point after the N-th line the calling thread runs in the client's own modules, for every N of a
call, so each line is hit in turn. After
each interrupt the test stops the gripper and checks that the client's lock is free, no reader role or
command id is left taken, and the next exchanges work. Deterministic in which lines are hit; bounded by the
number of lines a call runs.
"""

from __future__ import annotations

import dis
import sys
import threading
import time
from collections.abc import Callable
from pathlib import Path
from types import CodeType, FrameType
from typing import Any

import pytest

import grippers.drivers.wsg as wsg_package
from grippers.drivers.errors import GripperError, GripperTimeout
from grippers.drivers.wsg.client import WsgClient
from grippers.drivers.wsg.commands import Cmd, SystemFlags

from ..simhold import held

_ENGINE = {
    str(Path(wsg_package.__file__).parent / name)
    for name in (
        "callbacks.py",
        "client.py",
        "connection.py",
        "exchanges.py",
        "motion_exchanges.py",
        "reading.py",
        "handles.py",
        "interrupts.py",
    )
}


def _after(code: CodeType) -> dict[int, int]:
    """Offset of each instruction -> offset of the one laid out after it (cached per code object)."""
    table = _AFTER.get(code)
    if table is None:
        offsets = [i.offset for i in dis.get_instructions(code)]
        table = _AFTER[code] = dict(zip(offsets, offsets[1:], strict=False))
    return table


_AFTER: dict[CodeType, dict[int, int]] = {}


class _Interrupter:
    """Ctrl-C at the first point where Python would deliver a signal, from the ``n``-th line event on.

    A trace function raising at any line event would also hit points a real signal never reaches (the line
    of a ``with`` block's exit, before its lock is released: no code can survive that). Python runs signal
    handlers at function entry, at backward jumps (not ``JUMP_BACKWARD_NO_INTERRUPT``) and after a call
    returns (its eval breaker, still at the call's offset), so the interrupt is raised at the first such point
    once ``n`` lines of the client's modules have run: at a function's first instruction, after a backward
    jump, or at the instruction laid out right after a call that returned. Python 3.13 sometimes reports no
    event for that instruction (seen after a call that blocked); the next event is then at another offset and
    is not taken for a delivery point (it once was, outside the call's ``try``: a failure of this test, not
    of the client).
    """

    def __init__(self, n: int) -> None:
        self.n = n
        self.lines = 0
        self.fired = False
        self._previous: dict[int, tuple[int, str]] = {}  # frame id -> (offset, name) of its last opcode seen

    def __call__(self, frame: FrameType, event: str, arg: Any) -> Any:
        if frame.f_code.co_filename not in _ENGINE:
            return None  # no events for the rest of the world (pytest, threading, sockets)
        frame.f_trace_opcodes = True
        return self._local

    def _delivery_point(self, frame: FrameType) -> bool:
        previous = self._previous.get(id(frame))
        if previous is None:
            return True  # a function's entry
        offset, name = previous
        if name.startswith("JUMP_BACKWARD"):
            return name != "JUMP_BACKWARD_NO_INTERRUPT"
        return name.startswith("CALL") and _after(frame.f_code).get(offset) == frame.f_lasti

    def _local(self, frame: FrameType, event: str, arg: Any) -> Any:
        frame.f_trace_opcodes = True  # Python 3.13 needs it set from the local trace function too
        if self.fired:
            return self._local
        if event == "line":
            self.lines += 1
        elif event == "opcode" and self.n and self.lines >= self.n and self._delivery_point(frame):
            self.fired = True
            raise KeyboardInterrupt(f"after line event {self.n}")
        if event == "opcode":
            self._previous[id(frame)] = (frame.f_lasti, dis.opname[frame.f_code.co_code[frame.f_lasti]])
        elif event == "return":
            self._previous.pop(id(frame), None)
        return self._local


def _run_interrupted(call: Callable[[], object], n: int) -> _Interrupter:
    """Run ``call`` with an interrupt at its ``n``-th line; any exception but KeyboardInterrupt fails."""
    tracer = _Interrupter(n)
    sys.settrace(tracer)
    try:
        call()
    except KeyboardInterrupt:
        assert tracer.fired
    finally:
        sys.settrace(None)
    return tracer


def _healthy(c: WsgClient) -> None:
    """The lock is free for another thread and nobody holds the reading role for good: another thread's
    exchange completes (it would wait for the lock, or for a reader that never reads, and time out); then
    every id works."""
    took: list[bool] = []

    def probe() -> None:
        try:
            c.width(timeout=2.0)
            took.append(True)
        except GripperError:
            took.append(False)

    prober = threading.Thread(target=probe, daemon=True)
    prober.start()
    prober.join(5.0)
    assert took == [True], "another thread's exchange did not complete: the lock or the reading role is held"


def _stopped(c: WsgClient) -> None:
    """STOP goes out and the fingers come to rest."""
    c.stop(timeout=2.0)
    deadline = time.monotonic() + 3.0
    while c.system_state(timeout=2.0) & SystemFlags.SF_MOVING:
        assert time.monotonic() < deadline, "still moving after stop()"
        time.sleep(0.005)


@pytest.fixture
def served(wsg_sim, wsg_connect) -> tuple[Any, WsgClient]:
    """The simulator (its clock can be held still: tests/simhold.py) and a homed client of it."""
    server = wsg_sim("tcp://127.0.0.1:0", time_scale=20.0)
    c = wsg_connect(server.url, timeout=2.0, stale_ttl=0.2, stale_final_ttl=1.0)
    c.home()
    return server, c


@pytest.fixture
def client(served: tuple[Any, WsgClient]) -> WsgClient:
    return served[1]


def _lines_of(call: Callable[[], object]) -> int:
    tracer = _Interrupter(0)  # never fires: counts the lines of an uninterrupted call
    sys.settrace(tracer)
    try:
        call()
    finally:
        sys.settrace(None)
    return tracer.lines


@pytest.mark.parametrize("busy", [False, True], ids=["alone", "with-another-thread"])
def test_ctrl_c_at_every_line_of_a_state_query(client: WsgClient, busy: bool) -> None:
    """Interrupts at each line of ``width()``, alone and while another thread queries too (then the caller
    also sleeps while the other thread reads, the wait that once released an un-acquired lock)."""
    c = client
    done = threading.Event()
    errors: list[BaseException] = []

    lost = 0

    def other() -> None:
        nonlocal lost
        while not done.is_set():
            try:
                c.speed(timeout=0.5)
            except GripperTimeout:
                # Bytes the interrupted thread had just read when Ctrl-C came are gone with it (Python raises
                # the interrupt right after the socket call returned them), and they may hold this thread's
                # reply: a typed timeout for that one request, never a wedged id (checked below).
                lost += 1
            except BaseException as exc:  # noqa: BLE001 - reported below
                errors.append(exc)
                return

    helper = threading.Thread(target=other, daemon=True)
    if busy:
        helper.start()
    try:
        total = _lines_of(c.width)
        assert total > 10
        for n in range(1, total + 8):  # a few past the end: the call's line count varies with who reads
            _run_interrupted(c.width, n)
            _healthy(c)
            assert isinstance(c.width(timeout=2.0), float)
            assert c.loop(b"alive", timeout=2.0) == b"alive"
    finally:
        done.set()
        if busy:
            helper.join(5.0)
    assert not errors, errors
    assert lost <= total + 8  # at most one reply per interrupt
    assert isinstance(c.speed(timeout=2.0), float)
    assert c.connection_lost is None


def test_ctrl_c_at_every_line_of_a_motion_then_stop(client: WsgClient) -> None:
    """Interrupts at each of the first 200 lines of a blocking move (sending it, waiting for its
    E_CMD_PENDING, waiting for the end); each time the handler's STOP must go out and the fingers rest."""
    c = client
    fired = 0
    for n in range(1, 200):
        target = 20.0 if n % 2 else 80.0
        tracer = _run_interrupted(lambda t=target: c.preposition(t, 50.0), n)  # noqa: B023 - bound at once
        fired += tracer.fired
        _healthy(c)
        _stopped(c)
        assert isinstance(c.width(timeout=2.0), float)
    assert fired > 150  # most lines were hit: a motion of this length runs more than 200 lines
    c.preposition(50.0, 400.0, timeout=5.0)  # a whole motion still works
    assert c.width() == pytest.approx(50.0, abs=0.1)
    assert c.connection_lost is None


def test_ctrl_c_at_every_line_of_waiting_for_a_pending_motion(served: tuple[Any, WsgClient]) -> None:
    """``Pending.result()`` interrupted at each line: the motion keeps its slot (result may be called again),
    cancel() still stops it, and the result then reports the stop.

    The device is held still from the motion's start until it is stopped (tests/simhold.py): 90 mm at 5 mm/s
    is under a second at this time scale, and on a busy machine the interrupted call and the health check took
    longer (CI: "DID NOT RAISE", the motion had ended by itself before cancel())."""
    server, c = served
    for n in range(1, 60):
        start, end = (100.0, 10.0) if n % 2 else (10.0, 100.0)
        c.preposition(start, 400.0, timeout=5.0)
        with held(server):
            pending = c.preposition(end, 5.0, wait=False)  # held: still moving whatever the scheduler does
            assert pending is not None
            _run_interrupted(lambda p=pending: p.result(timeout=5.0), n)  # noqa: B023 - bound at once
            _healthy(c)
            # STOP, then the final reply; if the interrupt took that reply's bytes with it (see the state
            # query test), cancel() abandons the exchange so the id is free again after stale_final_ttl.
            pending.cancel(timeout=2.0)
            with pytest.raises(
                GripperError
            ):  # aborted (or abandoned): a stopped motion is never reported done
                pending.result(timeout=0.5)
        _stopped(c)
    assert c.request(Cmd.LOOP, b"x").payload[2:] == b"x"
