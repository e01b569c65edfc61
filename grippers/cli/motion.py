"""``grippers home|move|grasp|release|stop|ack``: one motion command each, in millimetres and newtons.

People type millimetres, mm/s and newtons; the Gripper API takes SI, so values are converted once, on the way
in, by :func:`grippers.cli.output.mm_to_m`. Each command prints the state reached afterwards, with units.
"""

from __future__ import annotations

import argparse
import sys
from collections.abc import Callable
from dataclasses import dataclass
from typing import TYPE_CHECKING, Any

from .common import (
    add_common,
    add_target,
    non_negative_float,
    opened_gripper,
    positive_float,
    stills_on_failure,
)
from .logs import issued_warnings
from .output import (
    EXIT_FAILED,
    EXIT_OK,
    RESULT_SCHEMA_ID,
    error_line,
    fmt_num,
    key_values,
    m_to_mm,
    mm_to_m,
    state_dict,
    write_json,
)

if TYPE_CHECKING:
    from grippers.gripper import GraspResult, Gripper, GripperState, MotionResult


@dataclass(frozen=True)
class MotionCommand:
    """One subcommand: its help, its extra arguments and the call it makes on an open Gripper."""

    name: str
    HELP: str
    EXAMPLE: str
    extra_arguments: Callable[[argparse.ArgumentParser], None]
    call: Callable[[Gripper, argparse.Namespace], Any]

    def add_arguments(self, parser: argparse.ArgumentParser) -> None:
        add_target(parser)
        self.extra_arguments(parser)
        if self.name in ("move", "grasp", "release"):
            parser.add_argument(
                "--home",
                action="store_true",
                help="home first (reference, calibrate or activate, as the family does) if the gripper is "
                "not referenced yet "
                "(needed on sim://, which starts a new simulator each time)",
            )
        if self.name in MOTIONS:
            parser.add_argument(
                "--motion-timeout",
                type=positive_float,
                metavar="SECONDS",
                help="give up if the motion has not ended by then (default: from the stroke and speed)",
            )
        add_common(parser)

    def run(self, args: argparse.Namespace) -> int:
        from grippers.errors import GripperError
        from grippers.gripper import GraspResult

        with opened_gripper(args) as gripper:  # a signal or an error stops what still moves, then closes
            if self.name in MOTIONS:
                _preflight(gripper, self.name, args)
                with stills_on_failure(gripper):  # a failed motion leaves the jaws still (issue 39 §2)
                    result = self.call(gripper, args)
            else:
                result = self.call(gripper, args)
            try:
                state: GripperState | None = gripper.state()
            except GripperError:  # the command's outcome matters more than a final read-back
                state = None
        # A grasp that found no part did what it was told but did not grip: scripts need a non-zero code.
        ok = not (isinstance(result, GraspResult) and not result.grasped)
        document = {
            "schema": RESULT_SCHEMA_ID,
            "command": self.name,
            "target": args.target,
            "ok": ok,
            "result": result_dict(result),
            "state": None if state is None else state_dict(state),
            "warnings": issued_warnings(),
        }
        if args.json:
            write_json(document)
        else:
            print(_result_text(self.name, document))
        if not ok:
            reason = result.reason if isinstance(result, GraspResult) else None
            print(error_line(self.name, f"no part gripped: {reason or 'unknown reason'}"), file=sys.stderr)
            return EXIT_FAILED
        return EXIT_OK


# The motions of grippers/commands.py's table, each with --motion-timeout and a preflight: written out, not
# imported, so `grippers --help` does not load the table; tests/test_command_table.py checks they agree.
MOTIONS = ("home", "move", "grasp", "release")


def _preflight(gripper: Gripper, command: str, args: argparse.Namespace) -> None:
    """Each CLI call is a new connection that cannot know what earlier calls left behind; a device would
    answer a motion with a bare E_ACCESS_DENIED (FAST STOP) or E_NOT_INITIALIZED (not referenced), so the
    state is read first and the error says what to do."""
    from grippers.errors import NotReferenced
    from grippers.gripper import FastStopActive

    # Values beyond the limits are a usage error whatever state the gripper is in: say that first.
    width, speed = getattr(args, "width", None), getattr(args, "speed", None)
    gripper.check(
        width=None if width is None else mm_to_m(width),
        speed=None if speed is None else mm_to_m(speed),
        force=getattr(args, "force", None),
        command=command,
    )
    state = gripper.state()
    if state.fast_stopped:
        raise FastStopActive(
            f"fast stop is active: acknowledge it first with: grippers ack {args.target}",
            device=gripper.name,
            command=command,
        )
    if command != "home" and not state.referenced:
        if not args.home:
            # Each sim:// command starts its own simulator: a separate `grippers home` cannot reach this one.
            how = (
                "add --home (each sim:// command starts a new simulator)"
                if args.target.startswith("sim:")
                else f"run `grippers home {args.target}` first, or add --home"
            )
            raise NotReferenced(  # the API's error for it, with the command line's way out
                f"{command} refused: not referenced: {how}",
                device=gripper.name,
                command=command,
            )
        with stills_on_failure(gripper):
            gripper.home(timeout=args.motion_timeout)


def result_dict(result: MotionResult | GraspResult | None) -> dict[str, Any] | None:
    """What a motion call returned, in the CLI's units (mm, N)."""
    from grippers.gripper import GraspResult, MotionResult

    if isinstance(result, GraspResult):
        return {
            "grasped": result.grasped,
            "width_mm": round(m_to_mm(result.width), 3),
            "force_n": None if result.force is None else round(result.force, 3),
            "grasp_state": result.state.value,
            "reason": result.reason,
        }
    if isinstance(result, MotionResult):
        return {"width_mm": round(m_to_mm(result.width), 3), "grasp_state": result.state.value}
    return None


def _result_text(name: str, document: dict[str, Any]) -> str:
    pairs: list[tuple[str, Any]] = [("command", f"{name}: {'done' if document['ok'] else 'failed'}")]
    result = document["result"] or {}
    if "grasped" in result:
        pairs.append(("grasped", "yes" if result["grasped"] else f"no ({result['reason']})"))
    if result.get("force_n") is not None:
        pairs.append(("grip force", fmt_num(result["force_n"], "N", 1)))
    state = document["state"]
    if state:
        pairs.append(("width", fmt_num(state["width_mm"], "mm", 2)))
        if state["force_n"] is not None:
            pairs.append(("force", fmt_num(state["force_n"], "N", 1)))
        if state["current_a"] is not None:
            pairs.append(("current", fmt_num(state["current_a"], "A", 3)))
        pairs += [("grasp state", state["grasp_state"]), ("faults", ", ".join(state["faults"]) or "none")]
    elif "width_mm" in result:
        pairs.append(("width", fmt_num(result["width_mm"], "mm", 2)))
    return key_values(pairs)


# --- the commands ------------------------------------------------------------------------------------------


def _speed(parser: argparse.ArgumentParser) -> None:
    parser.add_argument(
        "--speed", type=positive_float, metavar="MM/S", help="speed in mm/s (default: profile)"
    )


def _no_extra(parser: argparse.ArgumentParser) -> None:
    return None


def _home(g: Gripper, a: argparse.Namespace) -> None:
    g.home(timeout=a.motion_timeout)


def _move_args(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("width", type=non_negative_float, metavar="WIDTH_MM", help="opening width in mm")
    _speed(parser)


def _move(g: Gripper, a: argparse.Namespace) -> Any:
    return g.move(mm_to_m(a.width), mm_to_m(a.speed), timeout=a.motion_timeout)


def _grasp_args(parser: argparse.ArgumentParser) -> None:
    parser.add_argument(
        "width",
        type=non_negative_float,
        nargs="?",
        metavar="WIDTH_MM",
        help="nominal width of the part in mm (default: the smallest width, i.e. close fully)",
    )
    parser.add_argument("--force", type=positive_float, metavar="N", help="grip force in newtons")
    _speed(parser)


def _grasp(g: Gripper, a: argparse.Namespace) -> Any:
    width = g.limits.min_width if a.width is None else mm_to_m(a.width)
    return g.grasp(width, mm_to_m(a.speed), a.force, timeout=a.motion_timeout)


def _release_args(parser: argparse.ArgumentParser) -> None:
    parser.add_argument(
        "width",
        type=non_negative_float,
        nargs="?",
        metavar="WIDTH_MM",
        help="open to this width in mm (default: fully open)",
    )
    _speed(parser)


def _release(g: Gripper, a: argparse.Namespace) -> Any:
    return g.release(mm_to_m(a.width), mm_to_m(a.speed), timeout=a.motion_timeout)


def _stop_args(parser: argparse.ArgumentParser) -> None:
    parser.add_argument(
        "--fast", action="store_true", help="FAST STOP: an emergency stop that must be acknowledged (ack)"
    )


def _stop(g: Gripper, a: argparse.Namespace) -> None:
    if a.fast:
        g.fast_stop()
    else:
        g.stop()


def _ack(g: Gripper, a: argparse.Namespace) -> None:
    g.acknowledge()


home = MotionCommand(
    "home",
    "reference the axis: homing, calibration or activation, as the family does",
    "grippers home sim://\n         grippers home FAMILY+tcp://192.168.1.20   (your gripper's URL)",
    _no_extra,
    _home,
)
move = MotionCommand(
    "move",
    "move the fingers to an opening width in mm, without gripping",
    "grippers move 'sim://?time_scale=20' 30 --home\n"
    "         grippers move FAMILY+tcp://192.168.1.20 40 --speed 50   (your gripper's URL)",
    _move_args,
    _move,
)
grasp = MotionCommand(
    "grasp",
    "grip a part of a nominal width in mm with a force in N (exit 1 if no part was gripped)",
    "grippers grasp 'sim://?part_width_mm=20' 20 --force 30 --speed 50 --home\n"
    "         grippers grasp FAMILY+tcp://192.168.1.20 20 --force 30   (your gripper's URL)",
    _grasp_args,
    _grasp,
)
release = MotionCommand(
    "release",
    "release a gripped part: open to a width in mm (default fully open)",
    "grippers release sim:// 60 --home\n"
    "         grippers release FAMILY+tcp://192.168.1.20 60   (your gripper's URL)",
    _release_args,
    _release,
)
stop = MotionCommand(
    "stop",
    "stop the current motion (--fast: FAST STOP, acknowledge with `grippers ack`)",
    "grippers stop sim://\n         grippers stop FAMILY+tcp://192.168.1.20   (your gripper's URL)",
    _stop_args,
    _stop,
)
ack = MotionCommand(
    "ack",
    "acknowledge a FAST STOP or fault so the gripper accepts commands again",
    "grippers ack sim://\n         grippers ack FAMILY+tcp://192.168.1.20   (your gripper's URL)",
    _no_extra,
    _ack,
)
