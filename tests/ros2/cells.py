"""What the node tests share: a node process and its client under the names a ROS user would write."""

from __future__ import annotations

import os

from control_msgs.action import GripperCommand, ParallelGripperCommand
from sensor_msgs.msg import JointState
from std_srvs.srv import Trigger

from .rosclient import WAIT, CliProcess, RosClient, node_process

MM = 0.001
PART = 40 * MM  # the simulated part between the jaws
TOL = 1 * MM  # the node's default tolerance; also above the MSG's position quantum (~0.4 mm on msg-150)


def gripper_goal(position: float, max_effort: float = 0.0) -> GripperCommand.Goal:
    goal = GripperCommand.Goal()
    goal.command.position = position
    goal.command.max_effort = max_effort
    return goal


def parallel_goal(
    position: float, velocity: float | None = None, name: str | None = None
) -> ParallelGripperCommand.Goal:
    goal = ParallelGripperCommand.Goal()
    if name is not None:
        goal.command.name = [name]
    goal.command.position = [position]
    if velocity is not None:
        goal.command.velocity = [velocity]
    return goal


class Cell:
    """One node (namespace ``ns``) and a client: the names a ROS user would write."""

    def __init__(self, url: str, ns: str, *args: str, node: str = "gripper") -> None:
        self.ns = ns
        self.node = node
        self.proc: CliProcess = node_process(url, "--namespace", ns, "--name", node, *args)
        self.client = RosClient(f"test_client_{ns.strip('/')}")

    def name(self, tail: str) -> str:
        return f"{self.ns}/{self.node}/{tail}"

    def command(
        self, position: float, max_effort: float = 0.0, feedback: list | None = None
    ) -> tuple[int, object]:
        handle = self.client.send(
            GripperCommand, self.name("gripper_cmd"), gripper_goal(position, max_effort), feedback
        )
        assert handle.accepted, f"goal {position} rejected"
        return self.client.result(handle)

    def trigger(self, service: str) -> Trigger.Response:
        return self.client.call(Trigger, self.name(service))

    def joint_state(self) -> JointState:
        q = self.client.subscribe(JointState, f"{self.ns}/joint_states")
        return q.get(timeout=WAIT)

    def close(self) -> int:
        try:
            self.client.close()
        finally:
            rc = self.proc.terminate()
        return rc


def uniq(tag: str) -> str:
    return f"/t{os.getpid()}_{tag}"
