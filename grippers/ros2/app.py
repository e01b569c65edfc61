"""The process of ``grippers ros2``: one node per gripper in one rclpy context and one executor.

A plain node configures (opens its gripper) and activates at start; with ``lifecycle`` each node is an
rclpy LifecycleNode left unconfigured for ``ros2 lifecycle set`` to bring up, in the order a cell needs.
Each gripper fails on its own: its goals abort, its diagnostics say why, the other nodes go on.
"""

from __future__ import annotations

import threading
import time
from collections.abc import Callable
from dataclasses import dataclass, field
from typing import Any

from ..gripper import Gripper
from . import load_ros
from .node import GripperNode, NodeOptions

RESULT_GRACE = 0.3  # s the executor keeps spinning at shutdown so aborted goals' results reach their clients


@dataclass(frozen=True)
class GripperSpec:
    """A gripper to serve: how to open it, and its node's options."""

    opener: Callable[[], Gripper]
    options: NodeOptions = field(default_factory=NodeOptions)


def _plain_node(options: NodeOptions, context: Any) -> Any:
    from rclpy.node import Node

    return Node(options.name, namespace=options.namespace, context=context)


def _lifecycle_node(options: NodeOptions, context: Any) -> Any:
    """An rclpy LifecycleNode whose transitions drive the GripperNode set as its ``owner`` afterwards."""
    import lifecycle_msgs.msg  # type: ignore[import-not-found]  # noqa: F401 - ros-jazzy-lifecycle-msgs
    from rclpy.lifecycle import LifecycleNode, TransitionCallbackReturn

    class ManagedGripperNode(LifecycleNode):
        owner: GripperNode

        def _step(self, name: str, step: Callable[[], None]) -> Any:
            try:
                step()
            except Exception as exc:  # noqa: BLE001 - a failed transition is reported, the node stays
                self.get_logger().error(f"{name} failed: {exc}")
                return TransitionCallbackReturn.FAILURE
            return TransitionCallbackReturn.SUCCESS

        def on_configure(self, state: Any) -> Any:
            return self._step("configure", self.owner.configure)

        def on_activate(self, state: Any) -> Any:
            return self._step("activate", self.owner.activate)

        def on_deactivate(self, state: Any) -> Any:
            return self._step("deactivate", self.owner.deactivate)

        def on_cleanup(self, state: Any) -> Any:
            return self._step("cleanup", self.owner.cleanup)

        def on_shutdown(self, state: Any) -> Any:
            return self._step("shutdown", self.owner.shutdown)

        def on_error(self, state: Any) -> Any:
            return self._step("error processing", self.owner.shutdown)

    return ManagedGripperNode(options.name, namespace=options.namespace, context=context)


def spin(
    specs: list[GripperSpec],
    stop: threading.Event,
    *,
    args: list[str] | None = None,
    lifecycle: bool = False,
    ready: Callable[[list[GripperNode]], None] | None = None,
) -> None:
    """Run the nodes until ``stop`` is set (the CLI sets it on SIGINT/SIGTERM), then end them cleanly.

    rclpy's own signal handlers are off: the caller owns the signals, so an interrupt stops every gripper
    (running motion or not) and the goals end before the nodes and the DDS participant are destroyed (Fast
    DDS leaves shared-memory files behind when a participant is not), and only then are the grippers closed.
    """
    rclpy = load_ros()["rclpy"]
    from rclpy.executors import MultiThreadedExecutor
    from rclpy.signals import SignalHandlerOptions

    context = rclpy.Context()
    rclpy.init(args=args, context=context, signal_handler_options=SignalHandlerOptions.NO)
    gnodes: list[GripperNode] = []
    executor = None
    thread = None
    try:
        for spec in specs:
            make = _lifecycle_node if lifecycle else _plain_node
            rnode = make(spec.options, context)
            gnode = GripperNode(spec.opener, spec.options, rnode)
            gnodes.append(gnode)
            if lifecycle:
                rnode.owner = gnode
            else:
                gnode.configure()
                gnode.activate()
        # Threads per node: two goals (one preempting the other), a cancel, a service, two timers, feedback.
        executor = MultiThreadedExecutor(num_threads=4 + 4 * len(gnodes), context=context)
        for gnode in gnodes:
            executor.add_node(gnode.node)
        thread = threading.Thread(target=executor.spin, name="grippers-ros2-executor", daemon=True)
        thread.start()
        if ready is not None:
            ready(gnodes)
        while not stop.wait(0.2):
            pass
    finally:
        for gnode in gnodes:
            gnode.active = False
        halts = [threading.Thread(target=g.halt, daemon=True) for g in gnodes]  # all grippers stop at once
        for t in halts:
            t.start()
        for t in halts:
            t.join(5.0)
        if gnodes:
            # The action server sends a result from an executor task that runs after the execute callback
            # has returned; there is no event for "sent", so the executor spins on for a moment.
            time.sleep(RESULT_GRACE)
        if executor is not None:
            executor.shutdown(timeout_sec=5.0)
        if thread is not None:
            thread.join(5.0)
        for gnode in gnodes:
            try:
                gnode.cleanup()
            finally:
                gnode.destroy()
        if context.ok():
            rclpy.shutdown(context=context)
