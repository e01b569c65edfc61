"""``grippers record URL -o FILE.csv|FILE.jsonl|FILE.mcap [--do 'grasp 40 --force 20' ...]``: states and
commands over time, in SI-derived units (mm, mm/s, N, A), for tuning a grasp, for ``grippers plot`` and (MCAP)
for ROS 2 tools and Foxglove.

The output is opened before the gripper is: a path that cannot be written is a usage error before anything
moves (it used to be found after the motions, and the recording was lost). States are sampled by the
library's state stream in a background thread while the ``--do`` commands run one after another in this one,
each with its start and end (or error) stamped; the file is written at the end, also after Ctrl-C or a failed
command, so what was recorded is never lost.
"""

from __future__ import annotations

import argparse
import logging
import shlex
import sys
import threading
import time
from typing import Any

from .common import add_common, add_target, open_gripper, positive_float, state_dict
from .output import EXIT_FAILED, EXIT_OK, UsageError, error_line, write_json

log = logging.getLogger("grippers.cli.record")

HELP = (
    "record states (and the commands run with --do) over time to CSV, JSON Lines or MCAP, for grippers plot"
)
EXAMPLE = (
    "grippers record 'sim://wsg50?part_width_mm=40' -o grasp.csv --do home --do 'grasp 40 --force 20'\n"
    "         grippers record wsg+tcp://192.168.1.20 --duration 10 --rate 100 -o idle.jsonl\n"
    "         grippers record 'stepfoc+can://socketcan/can0?node=0' -o run.mcap --do home  (grippers[record])"
)
RECORD_RESULT_SCHEMA_ID = "grippers.record-result/1"

DO_COMMANDS = ("home", "move", "grasp", "release", "stop", "ack", "wait")
DEFAULT_DURATION = 5.0  # seconds, when there is nothing to --do
TAIL = 0.5  # seconds recorded after the last --do command, to see the jaws settle


def add_arguments(parser: argparse.ArgumentParser) -> None:
    add_target(parser)
    parser.add_argument(
        "-o",
        "--output",
        required=True,
        metavar="FILE",
        help="FILE.csv (header in FILE.csv.json), FILE.jsonl or FILE.mcap",
    )
    parser.add_argument(
        "--duration",
        type=positive_float,
        metavar="SECONDS",
        help=f"record this long (default: until the --do commands end + {TAIL:g} s, "
        f"else {DEFAULT_DURATION:g} s)",
    )
    parser.add_argument(
        "--rate",
        type=positive_float,
        default=50.0,
        metavar="HZ",
        help="state samples per second (default 50)",
    )
    parser.add_argument(
        "--do",
        action="append",
        default=[],
        metavar="COMMAND",
        help="a command to run while recording, as on the command line without the URL: 'home', "
        "'move 60 --speed 50', 'grasp 40 --force 20', 'release', 'stop', 'ack', 'wait 0.5' (repeatable)",
    )
    add_common(parser)


def _do_parser(name: str) -> argparse.ArgumentParser:
    from . import motion

    parser = argparse.ArgumentParser(prog=f"--do {name}", add_help=False, exit_on_error=False)
    if name == "wait":
        parser.add_argument("seconds", type=positive_float)
        return parser
    getattr(motion, name).extra_arguments(parser)
    parser.add_argument("--motion-timeout", type=positive_float, default=None)
    return parser


def parse_do(text: str) -> tuple[str, argparse.Namespace]:
    """'grasp 40 --force 20' -> ('grasp', its arguments); a mistake is a usage error before anything moves."""
    words = shlex.split(text)
    if not words or words[0] not in DO_COMMANDS:
        raise UsageError(f"--do {text!r}: expected one of {', '.join(DO_COMMANDS)}")
    try:
        args, rest = _do_parser(words[0]).parse_known_args(words[1:])
    except (argparse.ArgumentError, SystemExit) as exc:
        raise UsageError(f"--do {text!r}: {exc}") from None
    if rest:
        raise UsageError(f"--do {text!r}: unrecognized {' '.join(rest)}")
    return words[0], args


def _detail(result: Any) -> str | None:
    from .motion import result_dict

    plain = result_dict(result)
    if not plain:
        return None
    return " ".join(f"{k}={v}" for k, v in plain.items() if v is not None)


def run(args: argparse.Namespace) -> int:
    from . import motion
    from .recording import RecordingError, open_sink

    plan = [(text, *parse_do(text)) for text in args.do]
    try:
        sink = open_sink(args.output)  # a wrong name or an unwritable path is found before the gripper moves
    except RecordingError as exc:
        raise UsageError(str(exc)) from None
    rows: list[dict[str, Any]] = []
    lock = threading.Lock()
    start = time.time()
    failed: BaseException | None = None

    def sample(state: Any) -> None:
        row = {"t_s": round(state.timestamp - start, 6), "kind": "state", **state_dict(state)}
        with lock:
            rows.append(row)
            first = len(rows) == 1
        if first:  # -v: the gripper answers (a silent one shows as a recording that never says this)
            log.info("first state sampled at %.3f s", row["t_s"])

    def event(text: str, phase: str, detail: str | None = None) -> None:
        with lock:
            rows.append(
                {
                    "t_s": round(time.time() - start, 6),
                    "kind": "command",
                    "command": text,
                    "phase": phase,
                    "detail": detail,
                }
            )

    # One try from the open on: a Ctrl-C (or any failure) at any point either abandons the sink (nothing was
    # recorded: the gripper did not open) or writes it (never an empty file left behind, never a gripper
    # left open).
    gripper: Any = None
    stream = None
    try:
        gripper = open_gripper(args)
        start = time.time()
        stream = gripper.stream(rate_hz=args.rate, callback=sample)
        log.info(
            "recording %s to %s (Ctrl-C ends it; the file is written then)",
            args.target,
            ", ".join(sink.files),
        )
        for text, name, do_args in plan:
            event(text, "start")
            try:
                if name == "wait":
                    time.sleep(do_args.seconds)
                    result = None
                else:
                    result = getattr(motion, name).call(gripper, do_args)
            except Exception as exc:  # the recording is still written, with the error in it
                event(text, "failed", " ".join(str(exc).split()))
                failed = exc
                break
            event(text, "done", _detail(result))
        if args.duration is not None:
            end = start + args.duration
        else:
            end = time.time() + TAIL if plan else start + DEFAULT_DURATION
        while time.time() < end:
            time.sleep(min(0.05, max(0.0, end - time.time())))
    finally:
        if gripper is None:
            sink.abandon()
        else:
            if stream is not None:
                stream.close()
            gripper.close()
            with lock:
                ordered = sorted(rows, key=lambda r: r["t_s"])
            header = {"target": args.target, "start_unix": start, "rate_hz": args.rate, "do": list(args.do)}
            sink.write(header, ordered)
    samples = sum(1 for r in ordered if r["kind"] == "state")
    if args.json:
        write_json(
            {
                "schema": RECORD_RESULT_SCHEMA_ID,
                "target": args.target,
                "output": args.output,
                "format": sink.format,
                "files": sink.files,
                "states": samples,
                "command_events": len(ordered) - samples,
                "failed": None if failed is None else " ".join(str(failed).split()),
            }
        )
    else:
        events = len(ordered) - samples
        print(f"recorded {samples} states and {events} command events to {', '.join(sink.files)}")
    if failed is not None:
        print(error_line("record", failed), file=sys.stderr)
        return EXIT_FAILED
    return EXIT_OK
