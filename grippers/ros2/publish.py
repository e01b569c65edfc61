"""What a node publishes on its own: joint_states at ``--rate`` and /diagnostics once a period.

Both run on timers of their own mutually exclusive groups, so a slow device never piles their callbacks up.
joint_states' reads are the only regular device traffic; /diagnostics summarise them (grippers.ros2.health)
and read only the temperature, where the device has one. (joint_states on a thread of their own instead of a
timer, tried for target 14, changed neither the goals' latency nor the period jitter measurably on a loaded
machine; the timer stayed.)
"""

from __future__ import annotations

import math
import time
from collections.abc import Callable
from typing import Any

from ..errors import GripperError
from ..gripper import Gripper, GripperState
from ..states import Capability
from .health import Health
from .joints import JointLayout


def num(value: float | None) -> float:
    """A value the device may not report: NaN rather than a made-up 0."""
    return math.nan if value is None else float(value)


class StatePublisher:
    def __init__(self, node: Any, health: Health, joints: Callable[[], JointLayout]) -> None:
        from diagnostic_msgs.msg import DiagnosticArray, DiagnosticStatus, KeyValue
        from rclpy.callback_groups import MutuallyExclusiveCallbackGroup
        from sensor_msgs.msg import JointState

        self._JointState, self._Diag = JointState, (DiagnosticArray, DiagnosticStatus, KeyValue)
        self._Exclusive = MutuallyExclusiveCallbackGroup
        self.node = node
        self.health = health
        self._joints = joints
        self._logger = node.get_logger()
        self._joint_states = node.create_publisher(JointState, "joint_states", 10)
        self._diagnostics = node.create_publisher(DiagnosticArray, "/diagnostics", 10)
        self._timers: list[Any] = []
        self._gripper: Gripper | None = None
        self._state_error: str | None = None

    def start(self, gripper: Gripper, rate: float, diagnostics_period: float) -> None:
        self._gripper = gripper
        self._timers = [
            self.node.create_timer(1.0 / rate, self._publish_joint_state, self._Exclusive()),
            self.node.create_timer(diagnostics_period, self._publish_diagnostics, self._Exclusive()),
        ]

    def stop(self) -> None:
        for timer in self._timers:
            self.node.destroy_timer(timer)
        self._timers = []
        self._gripper = None

    def joint_state(self, st: GripperState) -> Any:
        joints = self._joints()
        msg = self._JointState()
        msg.header.stamp = self.node.get_clock().now().to_msg()
        msg.name = list(joints.names)
        msg.position = joints.positions(st.width)
        msg.velocity = joints.velocities(num(st.speed))
        msg.effort = joints.efforts(num(st.force))
        return msg

    def _publish_joint_state(self) -> None:
        gripper = self._gripper
        if gripper is None:
            return
        read_at = time.monotonic()
        try:
            st = gripper.state()
        except GripperError as exc:
            # Said once per change, not 50 times a second; the topic pauses until the device answers again.
            self.health.failed(str(exc))
            if str(exc) != self._state_error:
                self._logger.error(f"joint_states paused: {exc}")
                self._state_error = str(exc)
            return
        if self._state_error is not None:
            self._logger.info("joint_states resumed")
            self._state_error = None
        self._joint_states.publish(self.joint_state(st))
        self.health.saw(st, read_at)

    def _publish_diagnostics(self) -> None:
        DiagnosticArray, DiagnosticStatus, KeyValue = self._Diag
        gripper = self._gripper
        if gripper is not None and gripper.connected and Capability.TEMPERATURE in gripper.capabilities:
            try:
                self.health.temperature = gripper.temperature()
            except GripperError:
                self.health.temperature = None
        status = DiagnosticStatus()
        level, status.message = self.health.level()
        status.level = bytes([level])
        status.name = f"{self.node.get_name()}: gripper"
        status.hardware_id = self.health.hardware_id()
        status.values = [KeyValue(key=k, value=v) for k, v in self.health.values()]
        msg = DiagnosticArray()
        msg.header.stamp = self.node.get_clock().now().to_msg()
        msg.status = [status]
        self._diagnostics.publish(msg)
