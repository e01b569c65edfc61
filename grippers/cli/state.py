"""``grippers state URL``: the gripper's width, speed, force, grasp state and faults, once or ``--watch``.

``--watch --json`` writes one JSON document per line (JSON Lines) so a program can follow it.
"""

from __future__ import annotations

import argparse
import time
from typing import TYPE_CHECKING, Any

from ..units import millisecond_of
from .common import add_common, add_target, open_gripper, positive_float
from .logs import issued_warnings
from .output import EXIT_OK, STATE_SCHEMA_ID, fmt_num, key_values, state_dict, write_json

if TYPE_CHECKING:
    from grippers.gripper import GripperState

HELP = "show the gripper's state (width, force, grasp state, faults), once or live with --watch"
EXAMPLE = (
    "grippers state sim:// --json\n"
    "         grippers state FAMILY+tcp://192.168.1.20 --watch --rate 5   (your gripper's URL)"
)


def add_arguments(parser: argparse.ArgumentParser) -> None:
    add_target(parser)
    parser.add_argument("-w", "--watch", action="store_true", help="keep showing the state until Ctrl-C")
    parser.add_argument(
        "--rate",
        type=positive_float,
        default=2.0,
        metavar="HZ",
        help="--watch readings per second (default 2), the spelling of record and serve",
    )
    # The old spelling keeps working for scripts written before the commands agreed on --rate.
    parser.add_argument("--interval", type=positive_float, metavar="SECONDS", help=argparse.SUPPRESS)
    parser.add_argument(
        "-n",
        "--count",
        type=int,
        default=0,
        metavar="N",
        help="with --watch: stop after N readings (default: run until Ctrl-C)",
    )
    add_common(parser, json_help="print JSON (JSON Lines with --watch; schema in docs/cli.md)")


def document(target: str, state: GripperState) -> dict[str, Any]:
    return {
        "schema": STATE_SCHEMA_ID,
        "target": target,
        "time": round(state.timestamp, 6),
        "state": state_dict(state),
        "warnings": issued_warnings(),
    }


def render(doc: dict[str, Any]) -> str:
    """Aligned lines with units; a quantity the device does not report (speed and force on the MSG,
    current on the WSG) is left out rather than shown empty."""
    s = doc["state"]
    pairs: list[tuple[str, Any]] = [("width", fmt_num(s["width_mm"], "mm", 2))]
    if s["speed_mm_s"] is not None:
        pairs.append(("speed", fmt_num(s["speed_mm_s"], "mm/s", 1)))
    if s["force_n"] is not None:
        pairs.append(("force", fmt_num(s["force_n"], "N", 1)))
    if s["current_a"] is not None:
        pairs.append(("current", fmt_num(s["current_a"], "A", 3)))
    pairs += [
        ("grasp state", s["grasp_state"]),
        ("moving", "yes" if s["moving"] else "no"),
        ("referenced", "yes" if s["referenced"] else "no"),
        ("faults", ", ".join(s["faults"]) or "none"),
    ]
    return key_values(pairs)


def render_line(doc: dict[str, Any]) -> str:
    s = doc["state"]
    stamp = time.strftime("%H:%M:%S", time.localtime(doc["time"])) + f".{millisecond_of(doc['time']):03d}"
    faults = ",".join(s["faults"]) or "-"
    if s["force_n"] is None and s["current_a"] is not None:
        effort = f"current {fmt_num(s['current_a'], 'A', 3):>8}"
    else:
        effort = f"force {fmt_num(s['force_n'], 'N', 1):>8}"
    return (
        f"{stamp}  width {fmt_num(s['width_mm'], 'mm', 2):>10}  {effort}  "
        f"{s['grasp_state']:<11}  {'moving' if s['moving'] else 'still ':<6}  faults {faults}"
    )


def run(args: argparse.Namespace) -> int:
    gripper = open_gripper(args)
    try:
        if not args.watch:
            doc = document(args.target, gripper.state())
            if args.json:
                write_json(doc)
            else:
                print(render(doc))
            return EXIT_OK
        # The API's stream paces the readings and survives a slow terminal by dropping the oldest.
        rate = args.rate if args.interval is None else 1.0 / args.interval
        with gripper.stream(rate_hz=rate) as states:
            for readings, state in enumerate(states, start=1):
                doc = document(args.target, state)
                if args.json:
                    write_json(doc)
                else:
                    print(render_line(doc), flush=True)
                if args.count and readings >= args.count:
                    break
        return EXIT_OK
    finally:
        gripper.close()
