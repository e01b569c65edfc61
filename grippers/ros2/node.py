"""One ROS 2 node over one gripper: control_msgs actions, joint_states, /diagnostics, Trigger services.

Only message mapping and ROS plumbing live here; what a goal does is :mod:`grippers.ros2.goals`, the rules
that decide its outcome are ROS parameters (:mod:`grippers.ros2.params`), the joints a URDF expects are
:mod:`grippers.ros2.joints`, health is :mod:`grippers.ros2.health`, and every device exchange goes through
the :class:`~grippers.Gripper` API (its limits, its motion rule, its errors).

Life cycle: ``configure`` opens the gripper and starts joint_states and diagnostics, ``activate`` accepts
goals, ``deactivate`` stops the jaws and refuses goals, ``cleanup`` closes the gripper. A plain node runs
configure and activate at once; ``--lifecycle`` leaves them to ``ros2 lifecycle set`` (grippers.ros2.app).

Threads: actions run their (blocking) goals in a MultiThreadedExecutor with a reentrant callback group, so a
cancel, a newer goal or a ``~/stop`` arrives while a goal waits on the device; the timers have their own
mutually exclusive groups so a slow device never piles their callbacks up.
"""

from __future__ import annotations

import math
import threading
import time
from collections.abc import Callable
from dataclasses import dataclass
from typing import Any

from ..errors import GripperError
from ..gripper import Gripper, GripperState
from .goals import Arbiter, GoalEnded, GoalFailed, GoalRunner, Outcome, StallRule, Ticket, _started
from .health import Health
from .joints import JointLayout
from .params import DEFAULT_TOLERANCE, ParamBinder, Rules
from .publish import StatePublisher, num

DEFAULT_NAME = "gripper"
DEFAULT_JOINT = "gripper_joint"
DEFAULT_RATE = 50.0
LAYOUTS = ("default", "ros2_controllers")


@dataclass(frozen=True)
class NodeOptions:
    name: str = DEFAULT_NAME
    namespace: str = ""
    joint_names: tuple[str, ...] = (DEFAULT_JOINT,)
    rate: float = DEFAULT_RATE  # joint_states per second
    tolerance: float = DEFAULT_TOLERANCE  # m, goal_tolerance's default (--tolerance)
    feedback_period: float = 0.05  # s between action feedback messages while the jaws move
    actions: str = "default"  # or "ros2_controllers": ParallelGripperCommand at ~/gripper_cmd
    diagnostics_period: float = 1.0  # s


class GripperNode:
    """Owns one rclpy node over one gripper. Create after ``rclpy.init``; ``destroy()`` before shutdown.

    ``opener`` opens the gripper (at ``configure``); ``rclpy_node`` is the node to serve on (a plain Node,
    or a LifecycleNode whose transitions call :meth:`configure` and the others).
    """

    def __init__(self, opener: Callable[[], Gripper], options: NodeOptions, rclpy_node: Any) -> None:
        from control_msgs.action import GripperCommand, ParallelGripperCommand
        from rclpy.action import ActionServer, CancelResponse, GoalResponse
        from rclpy.action.server import GoalEvent
        from rclpy.callback_groups import ReentrantCallbackGroup
        from sensor_msgs.msg import JointState
        from std_srvs.srv import Trigger

        self._GoalResponse, self._CancelResponse, self._GoalEvent = GoalResponse, CancelResponse, GoalEvent
        self._GripperCommand, self._Parallel, self._JointState = (
            GripperCommand,
            ParallelGripperCommand,
            JointState,
        )
        self._opener = opener
        self.options = options
        self.node = rclpy_node
        self._logger = self.node.get_logger()
        self.gripper: Gripper | None = None
        self.active = False
        self.health = Health(period=options.diagnostics_period)
        self.arbiter = Arbiter()
        self._tickets: dict[bytes, Ticket] = {}
        self._tickets_lock = threading.Condition()  # notified when a goal ends (halt waits for them)
        self._unlisten: Callable[[], None] | None = None
        self.params = ParamBinder(
            self.node,
            Rules(goal_tolerance=options.tolerance, joints=JointLayout.of(options.joint_names)),
            self._check_limits,
        )
        actions = ReentrantCallbackGroup()
        gc_name, pg_name = (
            ("~/gripper_cmd", "~/parallel_gripper_cmd")
            if options.actions == "default"
            else (None, "~/gripper_cmd")
        )
        self._servers = []
        if gc_name is not None:
            self._servers.append(
                ActionServer(
                    self.node,
                    GripperCommand,
                    gc_name,
                    execute_callback=self._execute_gripper_command,
                    goal_callback=self._check_gripper_command,
                    cancel_callback=self._cancel,
                    callback_group=actions,
                )
            )
        self._servers.append(
            ActionServer(
                self.node,
                ParallelGripperCommand,
                pg_name,
                execute_callback=self._execute_parallel,
                goal_callback=self._check_parallel,
                cancel_callback=self._cancel,
                callback_group=actions,
            )
        )
        services = ReentrantCallbackGroup()
        self.node.create_service(Trigger, "~/home", self._home, callback_group=services)
        self.node.create_service(Trigger, "~/stop", self._stop, callback_group=services)
        self.node.create_service(Trigger, "~/acknowledge", self._acknowledge, callback_group=services)
        self.publisher = StatePublisher(self.node, self.health, lambda: self.rules.joints)

    @property
    def rules(self) -> Rules:
        return self.params.rules

    # -- life cycle ----------------------------------------------------------------------------------------

    def configure(self) -> None:
        """Open the gripper; joint_states and /diagnostics start. Raises what opening raises."""
        if self.gripper is not None:
            return
        gripper = self._opener()
        self.gripper = gripper
        self.health.url = gripper.url
        self.health.connected = gripper.connected
        try:
            self.health.info = gripper.info()
        except GripperError as exc:
            self._logger.warning(f"device info not read: {exc}")

        def on_connection(up: bool) -> None:
            self.health.connected = up
            if up:
                self.health.count("reconnects")
                self._logger.info("the gripper is connected again")
            else:
                self._logger.error("the gripper's connection is lost")

        self._unlisten = gripper.on_connection(on_connection)
        if self.rules.max_effort == 0 or self.rules.max_velocity == 0:  # a lifecycle node's "the profile's"
            _w, speed, force = gripper.check(command="defaults")
            from rclpy.parameter import Parameter

            self.node.set_parameters(
                [
                    Parameter("max_effort", value=self.rules.max_effort or float(force or 0.0)),
                    Parameter("max_velocity", value=self.rules.max_velocity or float(speed or 0.0)),
                ]
            )
        self.publisher.start(gripper, self.options.rate, self.options.diagnostics_period)

    def activate(self) -> None:
        self.active = True

    def deactivate(self) -> None:
        """Goals are refused from now on; a running one ends and the jaws stop."""
        self.active = False
        self.halt(why="the node is deactivated")

    def cleanup(self) -> None:
        """Stop publishing and close the gripper (configure opens it again)."""
        self.publisher.stop()
        gripper, self.gripper = self.gripper, None
        if self._unlisten is not None:
            self._unlisten()
            self._unlisten = None
        self.health.connected = False
        if gripper is not None:
            gripper.close()

    def shutdown(self) -> None:
        """From any state: the gripper stopped and closed."""
        self.active = False
        self.halt()
        self.cleanup()

    def halt(self, bound: float = 3.0, why: str = "the node is shutting down") -> None:
        """End every goal (they abort) and stop the gripper: it must not move on while nobody commands it.

        Waits (bounded) for the goals' execute callbacks to return, so their results are handed to the
        action server while the executor still spins to send them."""
        self.arbiter.end_all(why)
        gripper = self.gripper
        if gripper is not None and gripper.connected:
            # Unconditionally: a motion may run that no goal owns any more (issue 33: an interrupt stops
            # any running motion before closing), and a stop of jaws at rest changes nothing.
            try:
                gripper.stop()
            except GripperError as exc:
                self._logger.error(f"stop failed: {exc}")
        with self._tickets_lock:
            ended = self._tickets_lock.wait_for(lambda: not self._tickets, timeout=bound)
        if not ended:
            self._logger.warning("goals still running; their results may not reach the clients")

    def destroy(self) -> None:
        for server in self._servers:
            server.destroy()
        self.node.destroy_node()

    def joint_state(self, st: GripperState) -> Any:
        return self.publisher.joint_state(st)

    # -- goals: checked before acceptance, nothing sent for a refused one ----------------------------------

    def _check_limits(self, speed: float | None, force: float | None) -> str | None:
        if self.gripper is None:
            return None
        try:
            self.gripper.check(None, speed, force, command="parameters")
        except GripperError as exc:
            return str(exc)
        return None

    def _accept(self, action: str, values: Callable[[], tuple[float, float | None, float | None]]) -> Any:
        gripper = self.gripper
        why = None
        if gripper is None or not self.active:
            why = "the node is not active" if gripper is not None else "the gripper is not open (configure)"
        else:
            try:
                width, speed, force = values()
                gripper.check(width, speed, force, command=action)
            except (ValueError, GripperError) as exc:
                why = str(exc)
        if why is None:
            return self._GoalResponse.ACCEPT
        self._logger.warning(f"{action}: goal rejected: {why}")
        return self._GoalResponse.REJECT

    def _gripper_command_values(self, goal: Any) -> tuple[float, float | None, float | None]:
        effort = float(goal.command.max_effort)
        # max_effort 0 means the max_effort parameter (control_msgs leaves 0 undefined; ros2_controllers'
        # controllers use their max_effort parameter for it).
        return float(goal.command.position), self.rules.speed, (self.rules.force if effort == 0 else effort)

    def _check_gripper_command(self, goal: Any) -> Any:
        return self._accept("gripper_cmd", lambda: self._gripper_command_values(goal))

    def _parallel_values(self, goal: Any) -> tuple[float, float | None, float | None]:
        js = goal.command
        if len(js.position) != 1:  # as parallel_gripper_action_controller's goal_callback
            raise ValueError(f"one position expected, got {len(js.position)}")
        if len(js.velocity) > 1 or len(js.effort) > 1:
            raise ValueError("at most one velocity and one effort")
        joints = self.rules.joints
        width = joints.width_of(list(js.name), js.position[0])
        velocity = float(js.velocity[0]) if len(js.velocity) else 0.0
        effort = float(js.effort[0]) if len(js.effort) else 0.0
        speed = joints.speed_of(velocity) if velocity != 0 else self.rules.speed
        return width, speed, (effort if effort != 0 else self.rules.force)

    def _check_parallel(self, goal: Any) -> Any:
        return self._accept("parallel_gripper_cmd", lambda: self._parallel_values(goal))

    # -- cancel: the gripper stops at once -----------------------------------------------------------------

    def _cancel(self, goal_handle: Any) -> Any:
        with self._tickets_lock:
            ticket = self._tickets.get(bytes(goal_handle.goal_id.uuid))
        if ticket is not None and self.arbiter.end(ticket, "cancelled") and self.gripper is not None:
            try:
                self.gripper.stop()
            except GripperError as exc:
                self._logger.error(f"cancel: stop failed: {exc}")
        return self._CancelResponse.ACCEPT

    # -- execution -----------------------------------------------------------------------------------------

    def _state_outcome(self, target: float) -> Outcome:
        try:
            assert self.gripper is not None
            st = self.gripper.state()
        except (AssertionError, GripperError):
            return Outcome(math.nan, math.nan, False, False)
        return Outcome(st.width, num(st.force), False, abs(st.width - target) <= self.rules.goal_tolerance)

    def _end(self, goal_handle: Any, how: str, action: str, why: str = "") -> None:
        """Settle the goal handle: succeeded, aborted or canceled (counted for /diagnostics)."""
        if how == "canceled" and not goal_handle.is_cancel_requested:
            # A preempted goal: CANCELED as the controller's preempt_active_goal() sets it; rclpy's state
            # machine reaches CANCELED only through CANCELING.
            try:
                goal_handle._update_state(self._GoalEvent.CANCEL_GOAL)
            except Exception:  # noqa: BLE001 - no CANCELING from here: aborted is what remains
                how = "aborted"
        if how == "succeeded":
            goal_handle.succeed()
            self.health.count("succeeded")
        elif how == "canceled":
            self._logger.info(f"{action}: cancelled{': ' + why if why else ''}")
            goal_handle.canceled()
            self.health.count("cancelled")
        else:
            self._logger.warning(f"{action}: aborted: {why}")
            goal_handle.abort()
            self.health.count("aborted")

    def _run(
        self, action: str, goal_handle: Any, values: tuple[float, float | None, float | None], feedback: Any
    ) -> Outcome:
        """Run a goal to its end and settle the goal handle; returns the outcome for the result message."""
        width, speed, force = values
        rules = self.rules  # one set of rules for the whole goal
        key = bytes(goal_handle.goal_id.uuid)
        ticket = self.arbiter.begin(action, "preempted by a newer command")
        with self._tickets_lock:
            self._tickets[key] = ticket
        try:
            gripper = self.gripper
            if gripper is None or not self.active:
                self.arbiter.end(ticket, "the node is not active")
            elif goal_handle.is_cancel_requested:
                self.arbiter.end(ticket, "cancelled")
            if gripper is None:
                self._end(goal_handle, "aborted", action, ticket.ended or "")
                return Outcome(math.nan, math.nan, False, False)
            runner = GoalRunner(
                gripper,
                self.arbiter,
                ticket,
                feedback=lambda st: goal_handle.publish_feedback(feedback(st, width)),
                period=self.options.feedback_period,
                rule=StallRule(rules.goal_tolerance, rules.stall_velocity_threshold, rules.stall_timeout),
                recent=self.health.recent,
            )
            try:
                outcome = runner.run(width, speed, force)
            except GoalFailed as exc:
                self._end(goal_handle, "aborted", action, str(exc))
                return exc.outcome
            except (GoalEnded, GripperError) as exc:
                why = ticket.ended or str(exc)
                if ticket.ended == "cancelled" and self._cancel_state(goal_handle):
                    self._end(goal_handle, "canceled", action)
                elif why.startswith("preempted"):
                    self._end(goal_handle, "canceled", action, why)
                else:
                    self._end(goal_handle, "aborted", action, why)
                return self._state_outcome(width)
            except Exception as exc:  # a bug must not kill the node: the goal ends, the node stays
                self._end(goal_handle, "aborted", action, f"an unexpected error: {exc!r}")
                return self._state_outcome(width)
            if goal_handle.is_cancel_requested:
                self._end(goal_handle, "canceled", action)  # the motion ended before the cancel could stop it
            elif outcome.stalled and not outcome.reached_goal and not rules.allow_stalling:
                self._end(goal_handle, "aborted", action, "stalled (allow_stalling is false)")
            else:
                self._end(goal_handle, "succeeded", action)
            return outcome
        finally:
            self.arbiter.end(ticket, "finished")
            with self._tickets_lock:
                self._tickets.pop(key, None)
                self._tickets_lock.notify_all()

    @staticmethod
    def _cancel_state(goal_handle: Any, bound: float = 5.0) -> bool:
        """Whether the goal reached CANCELING. Our cancel callback stops the gripper before it returns, and
        rclpy moves the goal to CANCELING only after that, so the motion can end first: wait (bounded) for the
        transition, or ``canceled()`` would be an invalid transition from EXECUTING."""
        deadline = time.monotonic() + bound
        while not goal_handle.is_cancel_requested:
            if time.monotonic() > deadline or not goal_handle.is_active:
                return False
            time.sleep(0.005)
        return True

    def _gc_feedback(self, st: GripperState, target: float) -> Any:
        fb = self._GripperCommand.Feedback()
        fb.position = float(st.width)
        fb.effort = num(st.force)
        fb.stalled = False
        fb.reached_goal = abs(st.width - target) <= self.rules.goal_tolerance
        return fb

    def _execute_gripper_command(self, goal_handle: Any) -> Any:
        values = self._gripper_command_values(goal_handle.request)
        out = self._run("gripper_cmd", goal_handle, values, self._gc_feedback)
        result = self._GripperCommand.Result()
        result.position, result.effort = float(out.position), float(out.effort)
        result.stalled, result.reached_goal = out.stalled, out.reached_goal
        return result

    def _pg_feedback(self, st: GripperState, target: float) -> Any:
        fb = self._Parallel.Feedback()
        fb.state = self.joint_state(st)
        return fb

    def _execute_parallel(self, goal_handle: Any) -> Any:
        values = self._parallel_values(goal_handle.request)
        out = self._run("parallel_gripper_cmd", goal_handle, values, self._pg_feedback)
        result = self._Parallel.Result()
        joints = self.rules.joints
        result.state = self._JointState()
        result.state.header.stamp = self.node.get_clock().now().to_msg()
        result.state.name = list(joints.names)
        result.state.position = joints.positions(out.position)
        result.state.effort = joints.efforts(out.effort)
        result.stalled, result.reached_goal = out.stalled, out.reached_goal
        return result

    # -- services ------------------------------------------------------------------------------------------

    def _answer(self, response: Any, name: str, call: Callable[[Gripper], Any]) -> Any:
        try:
            if self.gripper is None:
                raise GoalEnded("the gripper is not open (configure the node)")
            call(self.gripper)
        except (GripperError, GoalEnded) as exc:
            response.success, response.message = False, str(exc)
            self._logger.warning(f"{name}: {exc}")
        else:
            response.success, response.message = True, "done"
        return response

    def _home(self, _request: Any, response: Any) -> Any:
        def home(gripper: Gripper) -> None:
            ticket = self.arbiter.begin("home", "preempted by ~/home")
            try:
                if not self.active:
                    raise GoalEnded("the node is not active")
                self.arbiter.start(ticket, lambda: _started(gripper.home(wait=False))).wait()
            finally:
                self.arbiter.end(ticket, "finished")

        return self._answer(response, "home", home)

    def _stop(self, _request: Any, response: Any) -> Any:
        def stop(gripper: Gripper) -> None:
            self.arbiter.end_all("stopped by ~/stop")
            gripper.stop()

        return self._answer(response, "stop", stop)

    def _acknowledge(self, _request: Any, response: Any) -> Any:
        return self._answer(response, "acknowledge", lambda g: g.acknowledge())
