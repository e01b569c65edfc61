"""``grippers ros2 URL``: run a ROS 2 node over any gripper the library opens (docs/ros2.md).

rclpy comes from the user's ROS 2 installation; it is imported inside ``run`` only, so ``grippers --help``
stays fast and works without ROS.
"""

from __future__ import annotations

import argparse
import signal
import sys
import threading
from typing import Any

from .common import positive_float

HELP = "run a ROS 2 node (control_msgs GripperCommand action, joint_states, Trigger services)"
EXAMPLE = (
    "grippers ros2 wsg+tcp://192.168.1.20 --name left_gripper --namespace /cell1\n"
    "         grippers ros2 sim://msg-150 --joint-name finger_joint --rate 100\n"
    "         grippers ros2 zenoh://left --ros-args -r joint_states:=/left/joint_states"
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
    parser.add_argument("target", metavar="URL", help="a connection URL, profile name or profile file")
    parser.add_argument("--name", type=_ros_name, default="gripper", help="node name (default gripper)")
    parser.add_argument("--namespace", type=_namespace, default="", metavar="NS", help="node namespace")
    parser.add_argument(
        "--joint-name",
        type=_ros_name,
        default="gripper_joint",
        metavar="JOINT",
        help="the joint in joint_states and ParallelGripperCommand (default gripper_joint)",
    )
    parser.add_argument(
        "--rate", type=positive_float, default=50.0, metavar="HZ", help="joint_states per second (default 50)"
    )
    parser.add_argument(
        "--tolerance",
        type=positive_float,
        default=1.0,
        metavar="MM",
        help="how close to the target counts as reached_goal (default 1 mm)",
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
        help="the rest of the line goes to ROS as with `ros2 run` (-r from:=to, -p name:=value, --log-level)",
    )


def run(args: argparse.Namespace) -> int:
    import grippers
    from grippers.ros2 import load_ros
    from grippers.ros2.node import NodeOptions, spin

    ros_args: list[str] = ["--ros-args", *args.ros_args] if args.ros_args else []
    load_ros()  # before opening the device: a missing ROS installation is said first, nothing opened
    stop = threading.Event()
    previous = {s: signal.signal(s, lambda *_: stop.set()) for s in (signal.SIGINT, signal.SIGTERM)}
    try:
        kwargs = {} if args.timeout is None else {"timeout": args.timeout}
        with grippers.open(args.target, **kwargs) as gripper:
            options = NodeOptions(
                name=args.name,
                namespace=args.namespace,
                joint_name=args.joint_name,
                rate=args.rate,
                tolerance=args.tolerance / 1000,
            )

            def ready(gnode: Any) -> None:
                node = gnode.node
                print(
                    f"{gripper.profile.model} at {gripper.url}: ROS 2 node {node.get_fully_qualified_name()} "
                    f"ready (joint {options.joint_name}, {options.rate:g} Hz)",
                    flush=True,
                )
                print("press Ctrl-C to stop", file=sys.stderr, flush=True)

            spin(gripper, options, stop, args=["grippers-ros2", *ros_args], ready=ready)
    finally:
        for s, handler in previous.items():
            signal.signal(s, handler)
    return 0
