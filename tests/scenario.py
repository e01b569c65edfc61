"""The one user scenario, run by tests/api (in-process and subprocess simulators) and tests/remote (served
over Zenoh): the same steps and the same assertions, whatever sits between the user and the device."""

from __future__ import annotations

import contextlib
import time
from collections.abc import Callable
from contextlib import AbstractContextManager

import pytest

import grippers
from grippers import GraspState, LimitError


def run_scenario(
    g: grippers.Gripper,
    profile: str,
    part: float,
    hold: Callable[[], AbstractContextManager[object]] = contextlib.nullcontext,
) -> None:
    """Home, move, read state during a slow motion, grasp a part of ``part`` m, limits, a timeout, a fast stop
    and its acknowledgement.

    ``hold()`` holds the simulated device still (its clock paused; it goes on answering) for the timeout
    check: at time scale 50 the slowest move lasts ~30 ms of wall time, and one slow poll on a busy machine
    saw it finished (issue 33 §5). Where nothing can hold the device (a served gripper), the check relies on
    the network's round trips being slower than 0.02 s of motion timeout."""
    assert g.profile.name == profile
    info = g.info()
    assert info.model == g.profile.model
    assert info.limits.max_width > part
    assert g.limits == info.limits

    g.home()
    assert g.state().referenced

    top = g.limits.max_width
    result = g.move(top * 0.95)
    assert result.width == pytest.approx(top * 0.95, abs=0.002)

    # State is readable while a motion runs. Slow enough that a state read (several exchanges) on a loaded
    # machine, or the served state (refreshed at 50 Hz), still sees the motion at time scale 50.
    slow = max(g.limits.min_speed, g.limits.max_speed / 40)
    handle = g.move(top * 0.5, slow, wait=False)
    seen_moving = False
    widths = []
    while not handle.done():
        st = g.state()
        widths.append(st.width)
        seen_moving |= st.moving
        time.sleep(0.002)
    handle.wait(5)
    assert seen_moving or len(set(widths)) > 1
    assert g.state().width == pytest.approx(top * 0.5, abs=0.002)

    g.release()
    grasp = g.grasp(part, force=g.limits.max_force / 2)
    assert grasp.grasped, grasp.reason
    assert grasp.state is GraspState.HOLDING
    assert grasp.width == pytest.approx(part, abs=0.003)
    assert g.state().grasp is GraspState.HOLDING

    g.release()
    assert g.state().grasp is GraspState.IDLE

    with pytest.raises(LimitError, match="outside"):
        g.move(top + 0.01)
    with pytest.raises(LimitError):
        g.grasp(part, force=g.limits.max_force * 2)

    # A motion that cannot finish in time raises a timeout, and the next command still works.
    with hold(), pytest.raises(grippers.GripperTimeout):
        g.move(top * 0.4, g.limits.min_speed, timeout=0.02)
    g.stop()
    assert g.state().width <= top

    g.fast_stop()
    with pytest.raises(grippers.GripperError, match="fast stop"):
        g.move(top * 0.6)
    g.acknowledge()
    assert "fast_stop" not in g.state().faults
    g.move(top * 0.6)
    assert g.state().width == pytest.approx(top * 0.6, abs=0.002)
