"""The controller's rules as ROS parameters, the joint conventions, the ros2_controllers action layout.

Each node runs as `grippers ros2` in a subprocess; the parameters are read and set through rclpy's parameter
services (what `ros2 param` calls) from an independent client node.
"""

from __future__ import annotations

import subprocess
import sys
import time
from collections.abc import Iterator

import pytest

from .conftest import SKIP_REASON

if SKIP_REASON:
    pytest.skip(SKIP_REASON, allow_module_level=True)

from action_msgs.msg import GoalStatus  # noqa: E402
from control_msgs.action import ParallelGripperCommand  # noqa: E402
from sensor_msgs.msg import JointState  # noqa: E402

from .cells import MM, PART, TOL, Cell, parallel_goal, uniq  # noqa: E402
from .rosclient import WAIT  # noqa: E402

pytestmark = pytest.mark.ros2

PARAMS = (
    "goal_tolerance",
    "allow_stalling",
    "stall_velocity_threshold",
    "stall_timeout",
    "max_effort",
    "max_velocity",
    "joint_names",
)


@pytest.fixture(scope="module")
def wsg(tmp_path_factory: pytest.TempPathFactory) -> Iterator[Cell]:
    """A WSG with a part, its parameters from a params file (per node) and from -p (every node)."""
    ns = uniq("rules")
    params = tmp_path_factory.mktemp("params") / "gripper.yaml"
    params.write_text(
        f"{ns}/gripper:\n"
        "  ros__parameters:\n"
        "    goal_tolerance: 0.002\n"
        "    joint_names: [left_finger_joint, right_finger_joint]\n"
    )
    cell = Cell(
        f"sim://wsg50?part_width_mm={PART / MM:g}",
        ns,
        "--ros-args",
        "-p",
        "stall_timeout:=2.5",
        "--params-file",
        str(params),
    )
    try:
        assert cell.trigger("home").success
        yield cell
    finally:
        assert cell.close() == 0, cell.proc.output()


def _node(cell: Cell) -> str:
    return f"{cell.ns}/{cell.node}"


def _set(cell: Cell, **values: object) -> None:
    for r in cell.client.set_parameters(_node(cell), **values):
        assert r.successful, r.reason


def test_the_parameters_are_declared_and_take_the_files_and_the_command_lines_values(wsg: Cell) -> None:
    names = wsg.client.list_parameters(_node(wsg))
    assert set(PARAMS) <= set(names), names
    got = dict(zip(PARAMS, wsg.client.get_parameters(_node(wsg), *PARAMS), strict=True))
    assert got["goal_tolerance"] == pytest.approx(0.002)  # --params-file
    assert got["stall_timeout"] == pytest.approx(2.5)  # -p
    assert got["allow_stalling"] is True  # our default (docs/ros2.md says why)
    assert got["stall_velocity_threshold"] == pytest.approx(0.001)
    assert got["max_effort"] > 0 and got["max_velocity"] > 0  # the profile's force and speed
    assert list(got["joint_names"]) == ["left_finger_joint", "right_finger_joint"]


@pytest.mark.parametrize(
    "values",
    [
        {"goal_tolerance": -0.001},
        {"stall_timeout": float("nan")},
        {"max_effort": 500.0},  # above the WSG 50's force limit
        {"joint_names": ["a", "b", "c"]},
        {"joint_names": ["a", "a"]},
        {"allow_stalling": 1},
    ],
    ids=["negative tolerance", "nan", "force limit", "three joints", "twice", "not a bool"],
)
def test_an_invalid_value_is_refused_and_nothing_changes(wsg: Cell, values: dict) -> None:
    (name,) = values
    before = wsg.client.get_parameters(_node(wsg), name)
    (result,) = wsg.client.set_parameters(_node(wsg), **values)
    assert not result.successful and result.reason
    assert wsg.client.get_parameters(_node(wsg), name) == before


def _js(cell: Cell) -> JointState:
    return cell.client.subscribe(JointState, f"{cell.ns}/joint_states").get(timeout=WAIT)


def test_two_finger_joints_each_at_half_the_width(wsg: Cell) -> None:
    status, result = wsg.command(0.08)  # GripperCommand: the position stays the width
    assert status == GoalStatus.STATUS_SUCCEEDED and abs(result.position - 0.08) <= TOL
    js = _js(wsg)
    assert list(js.name) == ["left_finger_joint", "right_finger_joint"]
    assert all(abs(p - 0.04) <= TOL / 2 for p in js.position), js.position
    # ParallelGripperCommand names one finger; its position is that finger's: 30 mm each, 60 mm open
    handle = wsg.client.send(
        ParallelGripperCommand,
        wsg.name("parallel_gripper_cmd"),
        parallel_goal(0.03, name="right_finger_joint"),
    )
    assert handle.accepted
    status, result = wsg.client.result(handle)
    assert status == GoalStatus.STATUS_SUCCEEDED and result.reached_goal
    assert list(result.state.name) == ["left_finger_joint", "right_finger_joint"]
    assert all(abs(p - 0.03) <= TOL / 2 for p in result.state.position), result.state.position
    assert all(abs(p - 0.03) <= TOL / 2 for p in _js(wsg).position)


@pytest.mark.parametrize(
    "goal",
    [parallel_goal(0.03, name="gripper_joint"), ParallelGripperCommand.Goal()],
    ids=["not a configured joint", "no position"],
)
def test_a_parallel_goal_for_another_joint_or_without_one_position_is_rejected(
    wsg: Cell, goal: ParallelGripperCommand.Goal
) -> None:
    assert not wsg.client.send(ParallelGripperCommand, wsg.name("parallel_gripper_cmd"), goal).accepted


def test_two_positions_are_rejected_as_the_controller_does(wsg: Cell) -> None:
    goal = parallel_goal(0.03, name="left_finger_joint")
    goal.command.name = ["left_finger_joint", "right_finger_joint"]
    goal.command.position = [0.03, 0.03]
    assert not wsg.client.send(ParallelGripperCommand, wsg.name("parallel_gripper_cmd"), goal).accepted


def test_allow_stalling_decides_whether_a_held_part_succeeds(wsg: Cell) -> None:
    for allow, expected in ((True, GoalStatus.STATUS_SUCCEEDED), (False, GoalStatus.STATUS_ABORTED)):
        _set(wsg, allow_stalling=allow)
        wsg.command(0.1)
        status, result = wsg.command(0.02, max_effort=20.0)
        assert status == expected, (allow, result)
        assert result.stalled and not result.reached_goal
        assert abs(result.position - PART) <= TOL
    _set(wsg, allow_stalling=True)
    wsg.command(0.1)


def test_goal_tolerance_decides_reached_goal(wsg: Cell) -> None:
    # the part stops the jaws at 40 mm: 6 mm from a 34 mm target
    wsg.command(0.1)
    _, result = wsg.command(0.034, max_effort=20.0)
    assert result.stalled and not result.reached_goal
    _set(wsg, goal_tolerance=0.01)
    try:
        wsg.command(0.1)
        _, result = wsg.command(0.034, max_effort=20.0)
        assert result.stalled and result.reached_goal
    finally:
        _set(wsg, goal_tolerance=0.002)
        wsg.command(0.1)


def test_the_stall_rule_stops_a_move_that_does_not_advance(wsg: Cell) -> None:
    """stall_velocity_threshold above any speed and stall_timeout 0: every move is 'not moving' at its first
    readings, so it ends stalled, stopped short of its target (on any device, blocked or not)."""
    wsg.command(0.03)
    _set(wsg, stall_velocity_threshold=10.0, stall_timeout=0.0, max_velocity=0.01)
    try:
        status, result = wsg.command(0.1)
        assert status == GoalStatus.STATUS_SUCCEEDED  # allow_stalling
        assert result.stalled and not result.reached_goal
        assert result.position < 0.1 - 10 * MM
        first = _js(wsg).position[0]
        assert abs(_js(wsg).position[0] - first) < 0.1 * MM  # stopped, not still moving
    finally:
        _set(wsg, stall_velocity_threshold=0.001, stall_timeout=2.5)
    status, result = wsg.command(0.1)  # the default rule: the same move reaches its target
    assert status == GoalStatus.STATUS_SUCCEEDED and result.reached_goal and not result.stalled


def test_max_velocity_and_max_effort_are_the_goals_defaults(wsg: Cell) -> None:
    _set(wsg, max_velocity=0.02, max_effort=15.0)
    try:
        wsg.command(0.1)
        start = time.monotonic()
        status, result = wsg.command(0.02)  # max_effort 0 in the goal
        took = time.monotonic() - start
        assert status == GoalStatus.STATUS_SUCCEEDED and result.stalled
        assert result.effort == pytest.approx(15.0, abs=1.0)
        # At 20 mm/s the jaws need at least distance / 20 mm/s; the default 50 mm/s takes less than
        # distance / 35 mm/s. A loaded machine only makes a goal slower, never faster (the feedback's
        # spacing, used before, bunched under load and read as 265 mm/s).
        travelled = 0.1 - result.position
        assert travelled > 0.02 and took >= travelled / 0.035, (travelled, took)
    finally:
        _set(wsg, max_velocity=0.05, max_effort=20.0)
        wsg.command(0.1)


# -- the ros2_controllers layout -------------------------------------------------------------------------


def test_the_ros2_controllers_layout_serves_parallel_gripper_command_at_gripper_cmd() -> None:
    cell = Cell("sim://wsg50", uniq("layout"), "--actions", "ros2_controllers", node="gripper_controller")
    try:
        assert cell.trigger("home").success
        handle = cell.client.send(ParallelGripperCommand, cell.name("gripper_cmd"), parallel_goal(0.05))
        assert handle.accepted
        status, result = cell.client.result(handle)
        assert status == GoalStatus.STATUS_SUCCEEDED and result.reached_goal
        types = dict(_action_types(cell))
        assert types.get(cell.name("gripper_cmd")) == ["control_msgs/action/ParallelGripperCommand"]
        assert cell.name("parallel_gripper_cmd") not in types
    finally:
        assert cell.close() == 0, cell.proc.output()


def _action_types(cell: Cell) -> list[tuple[str, list[str]]]:
    from rclpy.action import get_action_names_and_types

    return [(n, list(t)) for n, t in get_action_names_and_types(cell.client.node)]


@pytest.mark.parametrize(
    ("param", "said"),
    [("joint_names:=[a,b,c]", "one name"), ("goal_tolerance:=fine", "goal_tolerance")],
    ids=["three joints", "wrong type"],
)
def test_a_parameter_the_node_cannot_start_with_is_said_in_one_line(param: str, said: str) -> None:
    proc = subprocess.run(
        [
            sys.executable,
            "-m",
            "grippers",
            "ros2",
            "sim://wsg50",
            "--namespace",
            uniq("badp"),
            "--ros-args",
            "-p",
            param,
        ],
        capture_output=True,
        text=True,
        timeout=WAIT,
    )
    assert proc.returncode == 1, proc.stderr
    assert said in proc.stderr and "Traceback" not in proc.stderr, proc.stderr
