"""The node's ROS parameters: the rules of ros2_controllers' ``parallel_gripper_action_controller`` (jazzy,
``gripper_action_controller_parameters.yaml``) under the same names where the meaning is the same.

Declared on the node, so ``--ros-args -p NAME:=VALUE``, ``--params-file FILE``, ``ros2 param list/get/set``
all work. A set is validated as a whole (an invalid value is refused with the reason, nothing changes) and
the node's :class:`Rules` are replaced in one assignment, so a goal reads one consistent set of rules at its
start and keeps it to its end.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Sequence
from dataclasses import dataclass, replace
from typing import Any

from ..errors import GripperError
from .joints import JointLayout


class ParameterError(GripperError, ValueError):
    """A parameter given at start (``-p``, ``--params-file``) the node cannot run with."""


# The controller's defaults where ours differ are explained in docs/ros2.md ("allow_stalling").
DEFAULT_TOLERANCE = 0.001  # m (the controller: 0.01)
DEFAULT_STALL_VELOCITY = 0.001  # m/s (as the controller)
DEFAULT_STALL_TIMEOUT = 1.0  # s (as the controller)


@dataclass(frozen=True)
class Rules:
    """What decides a goal's outcome; one immutable set, swapped whole when a parameter changes."""

    goal_tolerance: float = DEFAULT_TOLERANCE
    allow_stalling: bool = True
    stall_velocity_threshold: float = DEFAULT_STALL_VELOCITY
    stall_timeout: float = DEFAULT_STALL_TIMEOUT
    max_effort: float = 0.0  # N; 0: the profile's default force
    max_velocity: float = 0.0  # m/s; 0: the profile's default speed
    joints: JointLayout = JointLayout(("gripper_joint",))

    @property
    def force(self) -> float | None:
        """The force for a goal that gives none (None: the profile's default)."""
        return self.max_effort or None

    @property
    def speed(self) -> float | None:
        return self.max_velocity or None


_FLOATS = ("goal_tolerance", "stall_velocity_threshold", "stall_timeout", "max_effort", "max_velocity")


def _descriptors(rules: Rules) -> list[tuple[str, Any, str]]:
    return [
        ("goal_tolerance", rules.goal_tolerance, "m: reached_goal when the jaws end within it of the target"),
        (
            "allow_stalling",
            rules.allow_stalling,
            "a goal stopped by a part: SUCCEEDED (true), ABORTED (false)",
        ),
        ("stall_velocity_threshold", rules.stall_velocity_threshold, "m/s: slower than this is not moving"),
        ("stall_timeout", rules.stall_timeout, "s not moving, short of the target, before a move is stalled"),
        ("max_effort", rules.max_effort, "N: the force of a goal whose effort is 0 or absent"),
        ("max_velocity", rules.max_velocity, "m/s: the speed of a goal that gives none"),
        (
            "joint_names",
            list(rules.joints.names),
            "one width joint, or two fingers at half the width",
        ),
    ]


class ParamBinder:
    """Declares the parameters on ``node`` and keeps ``rules`` in step with them.

    ``check_limits(speed, force)`` returns why the values are outside the gripper's limits (or None); it is
    called only when a gripper is open (a lifecycle node declares its parameters before configure).
    """

    def __init__(
        self, node: Any, rules: Rules, check_limits: Callable[[float | None, float | None], str | None]
    ) -> None:
        from rcl_interfaces.msg import ParameterDescriptor  # type: ignore[import-not-found]

        self._check_limits = check_limits
        self.rules = rules
        where = node.get_fully_qualified_name()
        for name, value, text in _descriptors(rules):
            try:
                node.declare_parameter(name, value, ParameterDescriptor(description=text))
            except Exception as exc:  # rclpy's type errors for a -p value of the wrong type
                raise ParameterError(f"{name}: {exc}", device=where, command="parameters") from None
        # --ros-args -p / --params-file values arrive with the declaration: read them back, checked.
        current = {name: node.get_parameter(name).value for name, _v, _t in _descriptors(rules)}
        self.rules, why = self._apply(current)
        if why:
            raise ParameterError(why, device=where, command="parameters")
        node.add_on_set_parameters_callback(self._on_set)

    def _apply(self, values: dict[str, Any]) -> tuple[Rules, str | None]:
        changes: dict[str, Any] = {}
        for name, value in values.items():
            if name in _FLOATS:
                if isinstance(value, bool) or not isinstance(value, int | float):
                    return self.rules, f"{name} must be a number, got {value!r}"
                v = float(value)
                if not math.isfinite(v) or v < 0:
                    return self.rules, f"{name} must be finite and >= 0, got {v:g}"
                changes[name] = v
            elif name == "allow_stalling":
                if not isinstance(value, bool):
                    return self.rules, f"allow_stalling must be a bool, got {value!r}"
                changes[name] = value
            elif name == "joint_names":
                try:
                    changes["joints"] = JointLayout.of(value)
                except ValueError as exc:
                    return self.rules, str(exc)
        new = replace(self.rules, **changes)
        if "max_effort" in changes or "max_velocity" in changes:
            why = self._check_limits(new.speed, new.force)
            if why:
                return self.rules, why
        return new, None

    def _on_set(self, params: Sequence[Any]) -> Any:
        from rcl_interfaces.msg import SetParametersResult

        known = {name for name, _v, _t in _descriptors(self.rules)}
        values = {p.name: p.value for p in params if p.name in known}
        new, why = self._apply(values)
        if why:
            return SetParametersResult(successful=False, reason=why)
        self.rules = new
        return SetParametersResult(successful=True)
