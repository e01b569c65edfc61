"""The ROS 2 node of ``grippers ros2``: control_msgs actions, joint_states, Trigger services over a Gripper.

Only message mapping and ROS plumbing live here; what a goal does is :mod:`grippers.ros2.goals`, and every
device exchange goes through the :class:`~grippers.Gripper` API (its limits, its motion rule, its errors).

Threads: actions run their (blocking) goals in a MultiThreadedExecutor with a reentrant callback group, so a
cancel, a newer goal or a ``~/stop`` arrives while a goal waits on the device; joint_states has its own
mutually exclusive group so a slow device never piles timer callbacks up.
"""

from __future__ import annotations

import logging
import math
import threading
import time
from dataclasses import dataclass
from typing import Any

from ..errors import GripperError, LimitError
from ..gripper import GraspState, Gripper, GripperState
from . import load_ros
from .goals import DEFAULT_TOLERANCE, Arbiter, GoalEnded, GoalFailed, GoalRunner, Outcome, Ticket, _started

log = logging.getLogger(__name__)

DEFAULT_NAME = "gripper"
DEFAULT_JOINT = "gripper_joint"
DEFAULT_RATE = 50.0
RESULT_GRACE = 0.3  # s the executor keeps spinning at shutdown so aborted goals' results reach their clients


@dataclass(frozen=True)
class NodeOptions:
    name: str = DEFAULT_NAME
    namespace: str = ""
    joint_name: str = DEFAULT_JOINT
    rate: float = DEFAULT_RATE  # joint_states per second
    tolerance: float = DEFAULT_TOLERANCE  # m, for reached_goal
    feedback_period: float = 0.05  # s between action feedback messages while the jaws move


def _num(value: float | None) -> float:
    return math.nan if value is None else float(value)


class GripperNode:
    """Owns one rclpy node over one gripper. Create after ``rclpy.init``; ``destroy()`` before shutdown."""

    def __init__(self, gripper: Gripper, options: NodeOptions, *, context: Any = None) -> None:
        ros = load_ros()
        rclpy = ros["rclpy"]
        from control_msgs.action import GripperCommand, ParallelGripperCommand
        from rclpy.action import ActionServer, CancelResponse, GoalResponse
        from rclpy.callback_groups import MutuallyExclusiveCallbackGroup, ReentrantCallbackGroup
        from rclpy.node import Node
        from sensor_msgs.msg import JointState
        from std_srvs.srv import Trigger

        self._rclpy = rclpy
        self._GoalResponse, self._CancelResponse = GoalResponse, CancelResponse
        self._GripperCommand, self._Parallel, self._JointState = (
            GripperCommand,
            ParallelGripperCommand,
            JointState,
        )
        self.gripper = gripper
        self.options = options
        self.arbiter = Arbiter()
        self._tickets: dict[bytes, Ticket] = {}
        self._tickets_lock = threading.Condition()  # notified when a goal ends (halt waits for them)
        self._closing = False
        self.node = Node(options.name, namespace=options.namespace, context=context)
        self._logger = self.node.get_logger()
        actions = ReentrantCallbackGroup()
        self._servers = [
            ActionServer(
                self.node,
                GripperCommand,
                "~/gripper_cmd",
                execute_callback=self._execute_gripper_command,
                goal_callback=self._check_gripper_command,
                cancel_callback=self._cancel,
                callback_group=actions,
            ),
            ActionServer(
                self.node,
                ParallelGripperCommand,
                "~/parallel_gripper_cmd",
                execute_callback=self._execute_parallel,
                goal_callback=self._check_parallel,
                cancel_callback=self._cancel,
                callback_group=actions,
            ),
        ]
        services = ReentrantCallbackGroup()
        self.node.create_service(Trigger, "~/home", self._home, callback_group=services)
        self.node.create_service(Trigger, "~/stop", self._stop, callback_group=services)
        self.node.create_service(Trigger, "~/acknowledge", self._acknowledge, callback_group=services)
        self._joint_states = self.node.create_publisher(JointState, "joint_states", 10)
        self._timer = self.node.create_timer(
            1.0 / options.rate, self._publish_joint_state, callback_group=MutuallyExclusiveCallbackGroup()
        )
        self._state_error: str | None = None

    # -- joint_states ------------------------------------------------------------------------------------

    def _joint_state(self, st: GripperState) -> Any:
        msg = self._JointState()
        msg.header.stamp = self.node.get_clock().now().to_msg()
        msg.name = [self.options.joint_name]
        msg.position = [float(st.width)]
        msg.velocity = [_num(st.speed)]
        msg.effort = [_num(st.force)]
        return msg

    def _publish_joint_state(self) -> None:
        try:
            st = self.gripper.state()
        except GripperError as exc:
            # Said once per change, not 50 times a second; the topic pauses until the device answers again.
            if str(exc) != self._state_error:
                self._logger.error(f"joint_states paused: {exc}")
                self._state_error = str(exc)
            return
        if self._state_error is not None:
            self._logger.info("joint_states resumed")
            self._state_error = None
        self._joint_states.publish(self._joint_state(st))

    # -- goals: checked before acceptance, nothing sent for a refused one ----------------------------------

    def _limits(self, width: float, speed: float | None, force: float | None, command: str) -> str | None:
        try:
            self.gripper.check(width, speed, force, command=command)
        except LimitError as exc:
            return str(exc)
        except GripperError as exc:
            return str(exc)
        return None

    def _reject(self, action: str, why: str) -> Any:
        self._logger.warning(f"{action}: goal rejected: {why}")
        return self._GoalResponse.REJECT

    @staticmethod
    def _gripper_command_values(goal: Any) -> tuple[float, float | None, float | None]:
        effort = float(goal.command.max_effort)
        # max_effort 0 means "the profile's default force" (control_msgs leaves 0 undefined; ros2_controllers'
        # gripper controller treats it as no limit, which a force-controlled gripper has no use for).
        return float(goal.command.position), None, (None if effort == 0 else effort)

    def _check_gripper_command(self, goal: Any) -> Any:
        width, speed, force = self._gripper_command_values(goal)
        why = self._limits(width, speed, force, "gripper_cmd")
        return self._reject("gripper_cmd", why) if why else self._GoalResponse.ACCEPT

    def _parallel_values(self, goal: Any) -> tuple[float, float | None, float | None]:
        js = goal.command
        names = list(js.name)
        if names and names != [self.options.joint_name]:
            raise ValueError(f"joint names {names} are not [{self.options.joint_name!r}]")
        if len(js.position) != 1:
            raise ValueError(f"one position expected, got {len(js.position)}")
        if len(js.velocity) > 1 or len(js.effort) > 1:
            raise ValueError("at most one velocity and one effort")
        speed = float(js.velocity[0]) if len(js.velocity) and js.velocity[0] != 0 else None
        force = float(js.effort[0]) if len(js.effort) and js.effort[0] != 0 else None
        return float(js.position[0]), speed, force

    def _check_parallel(self, goal: Any) -> Any:
        try:
            width, speed, force = self._parallel_values(goal)
        except ValueError as exc:
            return self._reject("parallel_gripper_cmd", str(exc))
        why = self._limits(width, speed, force, "parallel_gripper_cmd")
        return self._reject("parallel_gripper_cmd", why) if why else self._GoalResponse.ACCEPT

    # -- cancel: the gripper stops at once -----------------------------------------------------------------

    def _cancel(self, goal_handle: Any) -> Any:
        with self._tickets_lock:
            ticket = self._tickets.get(bytes(goal_handle.goal_id.uuid))
        if ticket is not None and self.arbiter.end(ticket, "cancelled"):
            try:
                self.gripper.stop()
            except GripperError as exc:
                self._logger.error(f"cancel: stop failed: {exc}")
        return self._CancelResponse.ACCEPT

    # -- execution -----------------------------------------------------------------------------------------

    def _state_outcome(self, target: float) -> Outcome:
        try:
            st = self.gripper.state()
        except GripperError:
            return Outcome(math.nan, math.nan, False, False)
        held = st.grasp is GraspState.HOLDING
        return Outcome(st.width, _num(st.force), held, abs(st.width - target) <= self.options.tolerance)

    def _run(
        self, action: str, goal_handle: Any, values: tuple[float, float | None, float | None], feedback: Any
    ) -> Outcome:
        """Run a goal to its end and settle the goal handle; returns the outcome for the result message."""
        width, speed, force = values
        key = bytes(goal_handle.goal_id.uuid)
        ticket = self.arbiter.begin(action, "preempted by a newer command")
        with self._tickets_lock:
            self._tickets[key] = ticket
        try:
            if self._closing:
                self.arbiter.end(ticket, "the node is shutting down")
            elif goal_handle.is_cancel_requested:
                self.arbiter.end(ticket, "cancelled")

            def send_feedback() -> None:
                if ticket.ended is None:
                    try:
                        goal_handle.publish_feedback(feedback(self.gripper.state(), width))
                    except GripperError:
                        pass  # the goal's own step reports a device that stopped answering

            runner = GoalRunner(
                self.gripper,
                self.arbiter,
                ticket,
                feedback=send_feedback,
                period=self.options.feedback_period,
                tolerance=self.options.tolerance,
            )
            try:
                outcome = runner.run(width, speed, force)
            except GoalFailed as exc:
                self._logger.warning(f"{action}: aborted: {exc}")
                goal_handle.abort()
                return exc.outcome
            except (GoalEnded, GripperError) as exc:
                why = ticket.ended or str(exc)
                if ticket.ended == "cancelled" and self._cancel_state(goal_handle):
                    self._logger.info(f"{action}: cancelled")
                    goal_handle.canceled()
                else:
                    self._logger.warning(f"{action}: aborted: {why}")
                    goal_handle.abort()
                return self._state_outcome(width)
            except Exception as exc:  # a bug must not kill the node: the goal ends, the node stays
                self._logger.error(f"{action}: aborted by an unexpected error: {exc!r}")
                goal_handle.abort()
                return self._state_outcome(width)
            if goal_handle.is_cancel_requested:
                goal_handle.canceled()  # the motion ended before the cancel could stop it
            else:
                goal_handle.succeed()
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
        fb.effort = _num(st.force)
        fb.stalled = st.grasp is GraspState.HOLDING
        fb.reached_goal = abs(st.width - target) <= self.options.tolerance
        return fb

    def _execute_gripper_command(self, goal_handle: Any) -> Any:
        values = self._gripper_command_values(goal_handle.request)
        out = self._run("gripper_cmd", goal_handle, values, self._gc_feedback)
        result = self._GripperCommand.Result()
        result.position, result.effort = float(out.position), float(out.effort)
        result.stalled, result.reached_goal = out.stalled, out.reached_goal
        return result

    def _outcome_state(self, out: Outcome) -> Any:
        js = self._JointState()
        js.header.stamp = self.node.get_clock().now().to_msg()
        js.name = [self.options.joint_name]
        js.position = [float(out.position)]
        js.effort = [float(out.effort)]
        return js

    def _pg_feedback(self, st: GripperState, target: float) -> Any:
        fb = self._Parallel.Feedback()
        fb.state = self._joint_state(st)
        return fb

    def _execute_parallel(self, goal_handle: Any) -> Any:
        values = self._parallel_values(goal_handle.request)
        out = self._run("parallel_gripper_cmd", goal_handle, values, self._pg_feedback)
        result = self._Parallel.Result()
        result.state = self._outcome_state(out)
        result.stalled, result.reached_goal = out.stalled, out.reached_goal
        return result

    # -- services ------------------------------------------------------------------------------------------

    def _answer(self, response: Any, name: str, call: Any) -> Any:
        try:
            call()
        except (GripperError, GoalEnded) as exc:
            response.success, response.message = False, str(exc)
            self._logger.warning(f"{name}: {exc}")
        else:
            response.success, response.message = True, "done"
        return response

    def _home(self, _request: Any, response: Any) -> Any:
        def home() -> None:
            ticket = self.arbiter.begin("home", "preempted by ~/home")
            try:
                self.arbiter.start(ticket, lambda: _started(self.gripper.home(wait=False))).wait()
            finally:
                self.arbiter.end(ticket, "finished")

        return self._answer(response, "home", home)

    def _stop(self, _request: Any, response: Any) -> Any:
        def stop() -> None:
            self.arbiter.end_all("stopped by ~/stop")
            self.gripper.stop()

        return self._answer(response, "stop", stop)

    def _acknowledge(self, _request: Any, response: Any) -> Any:
        return self._answer(response, "acknowledge", self.gripper.acknowledge)

    # -- life cycle ----------------------------------------------------------------------------------------

    def halt(self, bound: float = 3.0) -> None:
        """End every goal (they abort) and stop the gripper if one was running: the node is going away.

        Waits (bounded) for the goals' execute callbacks to return, so their ABORTED results are handed to
        the action server while the executor still spins to send them."""
        self._closing = True
        if self.arbiter.end_all("the node is shutting down"):
            try:
                self.gripper.stop()
            except GripperError as exc:
                self._logger.error(f"stop at shutdown failed: {exc}")
        with self._tickets_lock:
            ended = self._tickets_lock.wait_for(lambda: not self._tickets, timeout=bound)
        if not ended:
            self._logger.warning("goals still running at shutdown; their results may not reach the clients")

    def destroy(self) -> None:
        for server in self._servers:
            server.destroy()
        self.node.destroy_node()


def spin(
    gripper: Gripper,
    options: NodeOptions,
    stop: threading.Event,
    *,
    args: list[str] | None = None,
    ready: Any = None,
) -> None:
    """Run the node until ``stop`` is set (the CLI sets it on SIGINT/SIGTERM), then end it cleanly.

    rclpy's own signal handlers are off: the caller owns the signals, so a Ctrl-C stops a running motion
    and the goals end as aborted before the node and its DDS participant are destroyed (Fast DDS leaves
    shared-memory files behind when a participant is not).
    """
    ros = load_ros()
    rclpy = ros["rclpy"]
    from rclpy.executors import MultiThreadedExecutor
    from rclpy.signals import SignalHandlerOptions

    context = rclpy.Context()
    rclpy.init(args=args, context=context, signal_handler_options=SignalHandlerOptions.NO)
    gnode: GripperNode | None = None
    executor = None
    thread = None
    try:
        gnode = GripperNode(gripper, options, context=context)
        # Threads: two goals (one preempting the other), a cancel, a service, the timer, feedback.
        executor = MultiThreadedExecutor(num_threads=8, context=context)
        executor.add_node(gnode.node)
        thread = threading.Thread(target=executor.spin, name="grippers-ros2-executor", daemon=True)
        thread.start()
        if ready is not None:
            ready(gnode)
        while not stop.wait(0.2):
            pass
    finally:
        if gnode is not None:
            gnode.halt()
            # The action server sends a result from an executor task that runs after the execute callback
            # has returned; there is no event for "sent", so the executor spins on for a moment.
            time.sleep(RESULT_GRACE)
        if executor is not None:
            executor.shutdown(timeout_sec=5.0)
        if thread is not None:
            thread.join(5.0)
        if gnode is not None:
            gnode.destroy()
        if context.ok():
            rclpy.shutdown(context=context)
