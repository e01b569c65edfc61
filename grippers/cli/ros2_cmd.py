"""``grippers ros2 URL`` / ``NAME=URL ...``: ROS 2 nodes over any grippers the library opens (docs/ros2.md).

rclpy comes from the user's ROS 2 installation; it is imported inside ``run`` only, so ``grippers --help``
stays fast and works without ROS.
"""

from __future__ import annotations

import argparse
import functools
import signal
import sys
import threading
from typing import Any

from . import signals
from .common import positive_float

HELP = "run ROS 2 nodes (control_msgs gripper actions, joint_states, /diagnostics, Trigger services)"
EXAMPLE = (
    "grippers ros2 sim:// --joint-name finger_joint --rate 100\n"
    "         grippers ros2 FAMILY+tcp://192.168.1.20 --name left_gripper --namespace /cell1\n"
    "         grippers ros2 left=FAMILY+tcp://192.168.1.20 right=sim:// --namespace /cell1\n"
    "         grippers ros2 zenoh://left --lifecycle --ros-args --params-file gripper.yaml"
)


def _ros_name(text: str) -> str:
    """A ROS node name or joint name: letters, digits and underscores, not starting with a digit."""
    if not text or text[0].isdigit() or not all(c.isalnum() or c == "_" for c in text) or not text.isascii():
        raise argparse.ArgumentTypeError(f"{text!r} is not a ROS name (letters, digits, _; no leading digit)")
    return text


def _namespace(text: str) -> str:
    parts = [p for p in text.strip("/").split("/") if p]
    for p in parts:
        _ros_name(p)
    return "/" + "/".join(parts) if parts else ""


def add_arguments(parser: argparse.ArgumentParser) -> None:
    parser.add_argument(
        "targets",
        nargs="+",
        metavar="URL | NAME=URL",
        help="a connection URL, profile name or profile file; NAME=URL ...: one node per gripper, named NAME",
    )
    parser.add_argument(
        "--name", type=_ros_name, default="gripper", help="node name of a single URL (default gripper)"
    )
    parser.add_argument("--namespace", type=_namespace, default="", metavar="NS", help="node namespace")
    parser.add_argument(
        "--joint-name",
        type=_ros_name,
        default=None,
        metavar="JOINT",
        help="the width joint (default gripper_joint, NAME_joint for NAME=URL; two fingers: joint_names)",
    )
    parser.add_argument(
        "--rate", type=positive_float, default=50.0, metavar="HZ", help="joint_states per second (default 50)"
    )
    parser.add_argument(
        "--tolerance",
        type=positive_float,
        default=1.0,
        metavar="MM",
        help="goal_tolerance's default in mm (reached_goal; default 1 mm)",
    )
    parser.add_argument(
        "--actions",
        choices=("default", "ros2_controllers"),
        default="default",
        help="action names: default (GripperCommand at ~/gripper_cmd, ~/parallel_gripper_cmd) or "
        "ros2_controllers (ParallelGripperCommand at ~/gripper_cmd, as parallel_gripper_action_controller)",
    )
    parser.add_argument(
        "--lifecycle", action="store_true", help="managed nodes: unconfigured until `ros2 lifecycle set`"
    )
    parser.add_argument(
        "-t",
        "--timeout",
        type=positive_float,
        default=None,
        metavar="SECONDS",
        help="device exchange timeout",
    )
    parser.add_argument(
        "--ros-args",
        dest="ros_args",
        nargs=argparse.REMAINDER,
        default=[],
        metavar="ARG",
        help="the rest of the line goes to ROS as with `ros2 run` (-r, -p NAME:=VALUE, --params-file FILE)",
    )


def _specs(args: argparse.Namespace) -> list[Any]:
    """One GripperSpec per target: ``URL`` alone keeps its meaning (``--name``), ``NAME=URL`` names a node."""
    import grippers
    from grippers.ros2.app import GripperSpec
    from grippers.ros2.node import DEFAULT_JOINT, NodeOptions

    from .output import UsageError, mm_to_m
    from .serve import parse_targets

    targets = parse_targets(args.targets)
    named = [n for n, _t in targets if n is not None]
    if len(targets) > 1 and len(named) != len(targets):
        raise UsageError("several grippers need a name each: NAME=URL NAME=URL ...")
    if len(set(named)) != len(named):
        raise UsageError(f"a node name is given twice: {named}")
    if len(targets) > 1 and args.joint_name is not None:
        raise UsageError("--joint-name is for one gripper; several are named NAME_joint (or joint_names)")
    kwargs = {} if args.timeout is None else {"timeout": args.timeout}
    specs = []
    for name, target in targets:
        node = args.name if name is None else _ros_name_or_usage(name)
        joint = args.joint_name or (DEFAULT_JOINT if name is None else f"{name}_joint")
        options = NodeOptions(
            name=node,
            namespace=args.namespace,
            joint_names=(joint,),
            rate=args.rate,
            tolerance=mm_to_m(args.tolerance),
            actions=args.actions,
        )
        specs.append(GripperSpec(functools.partial(grippers.open, target, **kwargs), options))
    return specs


def _ros_name_or_usage(name: str) -> str:
    from .output import UsageError

    try:
        return _ros_name(name)
    except argparse.ArgumentTypeError as exc:
        raise UsageError(str(exc)) from None


def run(args: argparse.Namespace) -> int:
    from grippers.ros2 import load_ros
    from grippers.ros2.app import spin

    specs = _specs(args)
    ros_args: list[str] = ["--ros-args", *args.ros_args] if args.ros_args else []
    load_ros()  # before opening a device: a missing ROS installation is said first, nothing opened
    stop = threading.Event()
    # Ctrl-C, SIGTERM and SIGHUP all end the node the same way (grippers/cli/signals.py's rule, exit 0).
    previous = signals.ends_service(lambda *_: stop.set())
    previous[signal.SIGINT] = signal.signal(signal.SIGINT, lambda *_: stop.set())
    try:

        def ready(gnodes: list[Any]) -> None:
            for g in gnodes:
                fqn = g.node.get_fully_qualified_name()
                joints = ", ".join(g.rules.joints.names)
                if g.gripper is None:
                    print(f"ROS 2 lifecycle node {fqn} ready (unconfigured; joints {joints})", flush=True)
                else:
                    print(
                        f"{g.gripper.profile.model} at {g.gripper.url}: ROS 2 node {fqn} ready "
                        f"(joints {joints}, {g.options.rate:g} Hz)",
                        flush=True,
                    )
            print("press Ctrl-C to stop", file=sys.stderr, flush=True)

        spin(specs, stop, args=["grippers-ros2", *ros_args], lifecycle=args.lifecycle, ready=ready)
    finally:
        signals.restore(previous)
    return 0
