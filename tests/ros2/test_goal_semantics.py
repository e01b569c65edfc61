"""What a GripperCommand goal does (grippers/ros2/goals.py), on both simulators, without ROS.

These run in the normal suite: the part-finding rule is the heart of the node and must hold on every family
whether or not rclpy is installed. tests/ros2/test_node.py checks the same through real rclpy.
"""

from __future__ import annotations

import math
import subprocess
import sys

import pytest

import grippers
from grippers.gripper import GraspState
from grippers.ros2.goals import Arbiter, GoalEnded, GoalRunner, effort_of

from .conftest import SKIP_REASON

MM = 0.001
PART = 40 * MM


def _runner(gripper: grippers.Gripper, feedback: list[float] | None = None) -> GoalRunner:
    arbiter = Arbiter()
    return GoalRunner(
        gripper,
        arbiter,
        arbiter.begin("test", "preempted"),
        feedback=(lambda st: feedback.append(st.width)) if feedback is not None else (lambda st: None),
        period=0.02,
    )


@pytest.fixture(params=["sim://wsg50", "sim://msg-150"], ids=["wsg", "msg"])
def url(request: pytest.FixtureRequest) -> str:
    return str(request.param)


def test_a_closing_goal_holds_a_part_far_wider_than_the_target(url: str) -> None:
    # 20 mm asked, 40 mm part: outside the WSG's 5 mm clamping window, so its grasp alone says "no part".
    with grippers.open(f"{url}?part_width_mm={PART / MM:g}") as g:
        g.home()
        _runner(g).run(0.1, None, None)
        out = _runner(g).run(0.02, None, 20.0)
        assert out.stalled and not out.reached_goal
        assert abs(out.position - PART) <= 1 * MM
        assert out.effort > 0
        assert g.state().grasp is GraspState.HOLDING
        # a wider goal lets go of it (release) and ends where it asked
        out = _runner(g).run(0.09, None, None)
        assert out.reached_goal and not out.stalled
        assert g.state().grasp is not GraspState.HOLDING


def test_a_closing_goal_without_a_part_ends_at_its_target(url: str) -> None:
    with grippers.open(url) as g:
        g.home()
        _runner(g).run(0.1, None, None)
        feedback: list[float] = []
        out = _runner(g, feedback).run(0.03, None, 20.0)
        assert out.reached_goal and not out.stalled
        assert abs(out.position - 0.03) <= 1 * MM
        assert any(0.03 + 1 * MM < w < 0.1 - 1 * MM for w in feedback), feedback


def test_an_ended_ticket_starts_nothing() -> None:
    with grippers.open("sim://wsg50") as g:
        g.home()
        arbiter = Arbiter()
        old = arbiter.begin("old", "-")
        arbiter.begin("new", "preempted by new")  # the reason the previous ticket ends
        before = g.state().width
        runner = GoalRunner(g, arbiter, old, feedback=lambda st: None, period=0.02)
        with pytest.raises(GoalEnded, match="preempted by new"):
            runner.run(0.05, None, None)
        assert g.state().width == before and not g.state().moving


def test_unknown_effort_is_nan_not_zero() -> None:
    # The MSG reports a motor current, not a force: joint_states' effort is NaN there, never a made-up 0 N.
    with grippers.open("sim://msg-150") as g:
        st = g.state()
        assert st.force is None
        assert math.isnan(effort_of(st))


@pytest.mark.skipif(not SKIP_REASON, reason="rclpy is installed here: the missing-ROS message cannot show")
def test_without_ros_the_command_says_what_is_missing() -> None:
    proc = subprocess.run(
        [sys.executable, "-m", "grippers", "ros2", "sim://wsg50"], capture_output=True, text=True, timeout=60
    )
    assert proc.returncode == 1
    assert "rclpy" in proc.stderr and "docs/ros2.md" in proc.stderr
    assert "Traceback" not in proc.stderr
