"""Motions end honestly, on both families (issue 12 §3): one rule for overlapping motions (the newer one
supersedes), aborted motions raise, Ctrl-C stops the gripper before the exception leaves the call, a grasp
from closed jaws opens first, and done callbacks fire once.

Each test drives a simulator over a real transport through ``grippers.open``; each failed on the code before
the rule (a handle returned the newer motion's result, a stopped move returned its width, Ctrl-C left an MSG
moving, a grasp from closed jaws reported "without meeting a part").
"""

from __future__ import annotations

import os
import signal
import threading
import time
from typing import Any

import pytest

import grippers
from grippers import CommandFailed, GraspState, LimitError
from grippers.motions import MotionHandle

# Slow enough that a motion across the stroke at minimum speed takes seconds of wall time, fast enough that
# a calibration (MSG, ~8 s simulated) takes a fraction of a second.
TARGETS = {
    "wsg-tcp": "sim://wsg50?time_scale=4",
    "wsg-udp": "sim://wsg50?time_scale=4&transport=udp",
    "msg-can": "sim://msg-150?time_scale=8",
    "msg-pty": "sim://msg-150?time_scale=8&transport=pty",
}
BOTH = ["wsg-tcp", "msg-can"]
EVERY_TRANSPORT = {
    **TARGETS,
    "wsg-pty": "sim://wsg50?time_scale=4&transport=pty",
    "wsg-can": "sim://wsg50?time_scale=4&transport=can",
}


def _open(key: str, **query: Any) -> grippers.Gripper:
    url = EVERY_TRANSPORT[key] + "".join(f"&{k}={v}" for k, v in query.items())
    g = grippers.open(url)
    g.home()
    return g


def _slow_move(g: grippers.Gripper) -> MotionHandle[Any]:
    """A long motion: from wherever the jaws are to the far end at minimum speed."""
    lo, hi = g.limits.min_width, g.limits.max_width
    target = lo if g.state().width > (lo + hi) / 2 else hi
    handle = g.move(target, g.limits.min_speed, wait=False)
    assert isinstance(handle, MotionHandle)
    _until_moving(g)
    return handle


def _until_still(g: grippers.Gripper, bound: float = 3.0) -> grippers.GripperState:
    """The state once the jaws have come to rest (a stop decelerates; a loaded machine polls late)."""
    deadline = time.monotonic() + bound
    while (st := g.state()).moving:
        assert time.monotonic() < deadline, "still moving"
        time.sleep(0.005)
    return st


def _until_moving(g: grippers.Gripper, bound: float = 3.0) -> None:
    deadline = time.monotonic() + bound
    while not g.state().moving:
        assert time.monotonic() < deadline, "the motion never started"
        time.sleep(0.005)


@pytest.mark.parametrize("key", list(TARGETS))
def test_a_newer_motion_supersedes_and_the_older_handle_never_returns_its_result(key: str) -> None:
    with _open(key) as g:
        first = _slow_move(g)
        target = (g.limits.min_width + g.limits.max_width) / 2
        result = g.move(target)  # the newer motion wins and reports its own result
        assert result.width == pytest.approx(target, abs=0.002)
        with pytest.raises(CommandFailed, match="superseded by move to"):
            first.wait(0)  # settled the moment the newer motion started
        first.join(5.0)
        _until_still(g)


@pytest.mark.parametrize("key", BOTH)
def test_a_motion_superseded_before_it_was_sent_sends_nothing(key: str) -> None:
    with _open(key) as g:
        running = _slow_move(g)
        queued = g.move(g.limits.max_width * 0.3, wait=False)  # waits for the running one to end
        last = g.move(g.limits.max_width * 0.6, wait=False)  # supersedes the queued one at once
        assert isinstance(queued, MotionHandle) and isinstance(last, MotionHandle)
        assert last.wait(30).width == pytest.approx(g.limits.max_width * 0.6, abs=0.002)
        for old in (running, queued):
            with pytest.raises(CommandFailed, match="superseded"):
                old.wait(0)


@pytest.mark.parametrize("key", list(TARGETS))
@pytest.mark.parametrize("how", ["stop", "fast_stop", "cancel"])
def test_stop_fast_stop_and_cancel_abort_the_running_motion(key: str, how: str) -> None:
    with _open(key) as g:
        handle = _slow_move(g)
        getattr(handle if how == "cancel" else g, how)()
        with pytest.raises(CommandFailed, match=rf"aborted by {how}\(\)") as caught:
            handle.wait(5.0)
        assert "superseded" not in str(caught.value)
        handle.join(5.0)
        if how == "fast_stop":
            assert g.state().fast_stopped
            g.acknowledge()
        st = _until_still(g)
        assert g.limits.min_width < st.width < g.limits.max_width  # stopped on the way


@pytest.mark.parametrize("key", BOTH)
def test_stop_aborts_a_blocking_call_in_another_thread(key: str) -> None:
    with _open(key) as g:
        lo, hi = g.limits.min_width, g.limits.max_width
        target = lo if g.state().width > (lo + hi) / 2 else hi
        outcome: list[BaseException | object] = []

        def run() -> None:
            try:
                outcome.append(g.move(target, g.limits.min_speed))
            except BaseException as exc:
                outcome.append(exc)

        thread = threading.Thread(target=run)
        thread.start()
        _until_moving(g)
        g.stop()
        thread.join(10)
        assert len(outcome) == 1 and isinstance(outcome[0], CommandFailed), outcome
        assert "aborted by stop()" in str(outcome[0])


@pytest.mark.parametrize("key", list(EVERY_TRANSPORT))
def test_ctrl_c_during_a_blocking_motion_stops_the_gripper_first(key: str) -> None:
    with _open(key) as g:
        lo, hi = g.limits.min_width, g.limits.max_width
        target = lo if g.state().width > (lo + hi) / 2 else hi
        main = threading.get_ident()

        def interrupt() -> None:
            _until_moving(g)
            signal.pthread_kill(main, signal.SIGINT)

        threading.Thread(target=interrupt, daemon=True).start()
        with pytest.raises(KeyboardInterrupt):
            g.move(target, g.limits.min_speed)
        # The gripper was stopped before the exception left move(): it comes to rest at once and stays put
        # (without the stop it would travel on for seconds: several mm in the 0.2 s below).
        first = _until_still(g, bound=0.5)
        time.sleep(0.2)
        assert g.state().width == pytest.approx(first.width, abs=0.001)
        assert abs(first.width - target) > 0.005
        g.move((lo + hi) / 2)  # and the gripper is usable


@pytest.mark.parametrize("key", BOTH)
def test_done_callbacks_fire_once_from_the_ending_thread_or_at_once(key: str) -> None:
    with _open(key) as g:
        calls: list[tuple[MotionHandle[Any], str]] = []
        handle = _slow_move(g)
        handle.add_done_callback(lambda h: calls.append((h, threading.current_thread().name)))
        g.stop()  # ends it: the motion's thread (WSG: E_CMD_ABORTED came back first) or this one
        assert [h for h, _ in calls] == [handle]
        assert calls[0][1] in (threading.current_thread().name, "grippers-move")
        late: list[MotionHandle[Any]] = []
        handle.add_done_callback(late.append)  # already done: called at once, here
        assert late == [handle]
        second = g.move(g.limits.max_width / 2, wait=False)
        assert isinstance(second, MotionHandle)
        fired = threading.Event()
        second.add_done_callback(lambda h: fired.set() if h.wait(0) else None)
        assert fired.wait(10)
        assert [h for h, _ in calls] == [handle]  # the first one fired only once


@pytest.mark.parametrize("key", ["msg-can", "msg-pty", "wsg-tcp"])
def test_grasp_from_jaws_inside_the_part_opens_first(key: str) -> None:
    part = 0.040
    with _open(key, **({} if key.startswith("wsg") else {"part_width_mm": 40})) as g:
        if key.startswith("wsg"):
            g.move(0.010)  # an MSG rests closed after calibration; bring a WSG there
            g.simulator.place_part(40.0)  # then put the part where it will be once the jaws open
        assert g.state().width < part
        result = g.grasp(part, force=g.limits.max_force / 2)
        assert isinstance(result, grippers.GraspResult)
        assert result.grasped, result.reason
        assert result.state is GraspState.HOLDING
        assert result.width == pytest.approx(part, abs=0.003)


@pytest.mark.parametrize("timeout", [float("nan"), -1.0, "soon"])
def test_handle_wait_refuses_a_timeout_that_is_no_timeout(timeout: Any) -> None:
    with grippers.open("sim://wsg50?time_scale=50") as g:
        g.home()
        handle = g.move(0.05, wait=False)
        assert isinstance(handle, MotionHandle)
        with pytest.raises(LimitError, match="timeout"):
            handle.wait(timeout)
        assert handle.wait(1e10).width == pytest.approx(0.05, abs=0.002)  # OverflowError before


@pytest.mark.skipif(os.name != "posix", reason="signals")
def test_ctrl_c_in_handle_wait_leaves_the_motion_to_its_owner() -> None:
    with _open("wsg-tcp") as g:
        handle = _slow_move(g)
        main = threading.get_ident()
        threading.Timer(0.05, lambda: signal.pthread_kill(main, signal.SIGINT)).start()
        with pytest.raises(KeyboardInterrupt):
            handle.wait(10)
        assert not handle.done() and g.state().moving  # documented: cancel() stops it
        handle.cancel()
        with pytest.raises(CommandFailed, match="aborted by cancel"):
            handle.wait(5)
