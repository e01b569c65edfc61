"""``grippers record [NAME=]URL... -o FILE.csv|.jsonl|.mcap [--do '[NAME:] grasp 40 --force 20' ...]``:
states and commands of one or several grippers over time, in one file, in SI-derived units (mm, mm/s, N, A),
for tuning a grasp, for ``grippers plot`` and (MCAP) for ROS 2 tools and Foxglove.

The output is opened before the grippers are: a path that cannot be written is a usage error before anything
moves. The :class:`grippers.recorder.Recorder` samples every gripper in the background and writes rows as
they come, while the ``--do`` commands run one after another here, each with its start and end (or error)
stamped. A ``--do`` without a ``NAME:`` runs on every gripper at once: each call runs in a thread of its own
and this thread waits for them, so a Ctrl-C (or a failure) here stops every gripper that still moves before
anything closes (issue 33 §1: a motion started without waiting must not run on after exit).
"""

from __future__ import annotations

import argparse
import logging
import re
import shlex
import sys
import threading
import time
from dataclasses import dataclass
from typing import Any

from . import signals
from .common import add_common, open_gripper, positive_float, still_after_failure
from .output import EXIT_FAILED, EXIT_OK, UsageError, error_line, write_json

log = logging.getLogger("grippers.cli.record")

HELP = (
    "record states (and the commands run with --do) of one or several grippers over time to CSV, "
    "JSON Lines or MCAP, for grippers plot"
)
EXAMPLE = (
    "grippers record 'sim://?part_width_mm=40' -o grasp.csv --do home --do 'grasp 40 --force 20'\n"
    "         grippers record left=FAMILY+tcp://192.168.1.20 right=sim:// -o both.csv --do home "
    "--do 'left: grasp 40'\n"
    "         grippers record 'FAMILY+can://socketcan/can0?node=0' -o run.mcap --do home  (the record extra)"
)
RECORD_RESULT_SCHEMA_ID = "grippers.record-result/1"

DO_COMMANDS = ("home", "move", "grasp", "release", "stop", "ack", "wait")
DEFAULT_DURATION = 5.0  # seconds, when there is nothing to --do
TAIL = 0.5  # seconds recorded after the last --do command, to see the jaws settle
MAX_SECONDS = 86400.0  # a --do wait or --motion-timeout: a day at most (1e308 s is a typing mistake)
STOP_BOUND = 5.0  # seconds a stop after Ctrl-C may take before the grippers are closed anyway
_NAMED = re.compile(r"([A-Za-z][A-Za-z0-9_]{0,63})=(.+)")
_PREFIX = re.compile(r"\s*([A-Za-z][A-Za-z0-9_]{0,63})\s*:(.*)", re.S)


def add_arguments(parser: argparse.ArgumentParser) -> None:
    parser.add_argument(
        "targets",
        nargs="+",
        metavar="[NAME=]URL",
        help="a connection URL, profile name or profile file, as for every command; several record into one "
        "file, each named NAME (default: gripper for one, g1, g2, ... for several)",
    )
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
        help="state samples per second, per gripper (default 50)",
    )
    parser.add_argument(
        "--do",
        action="append",
        default=[],
        metavar="COMMAND",
        help="a command to run while recording, as on the command line without the URL: 'home', "
        "'move 60 --speed 50', 'grasp 40 --force 20', 'release', 'stop', 'ack', 'wait 0.5' (repeatable); "
        "'NAME: grasp 40' runs on one gripper, without NAME: on every gripper at once",
    )
    add_common(parser)


# --- targets and --do --------------------------------------------------------------------------------------


def named_targets(targets: list[str]) -> dict[str, str]:
    """``["left=URL1", "URL2"]`` -> ``{"left": URL1, "g2": URL2}``; one unnamed target is ``gripper``."""
    from grippers.recording import DEFAULT_NAME

    out: dict[str, str] = {}
    for number, text in enumerate(targets, start=1):
        match = _NAMED.fullmatch(text)
        name, url = (match.group(1), match.group(2)) if match else (f"g{number}", text)
        if len(targets) == 1 and not match:
            name = DEFAULT_NAME
        if name in out:
            raise UsageError(f"{text}: the name {name!r} is given twice (NAME=URL names each gripper once)")
        out[name] = url
    return out


def _seconds(text: str) -> float:
    value = positive_float(text)
    if value > MAX_SECONDS:
        raise argparse.ArgumentTypeError(f"at most {MAX_SECONDS:g} s (a day), not {text!r}")
    return value


class _DoError(Exception):
    pass


class _DoParser(argparse.ArgumentParser):
    """argparse that raises what it would print: "the following arguments are required: WIDTH_MM", not the
    SystemExit(2) whose str() is "2" (issue 33 §3: ``--do move`` printed "error: --do 'move': 2")."""

    def error(self, message: str) -> Any:
        raise _DoError(message)


def _do_parser(name: str) -> argparse.ArgumentParser:
    from . import motion

    parser = _DoParser(prog=f"--do {name}", add_help=False, exit_on_error=False)
    if name == "wait":
        parser.add_argument("seconds", type=_seconds, metavar="SECONDS")
        return parser
    getattr(motion, name).extra_arguments(parser)
    parser.add_argument("--motion-timeout", type=_seconds, default=None, metavar="SECONDS")
    return parser


@dataclass(frozen=True)
class Step:
    text: str  # as given to --do
    gripper: str | None  # None: every gripper (wait: none)
    name: str  # home, move, ..., wait
    args: argparse.Namespace


def parse_do(text: str, names: list[str] | None = None) -> Step:
    """'[NAME:] grasp 40 --force 20' -> a Step; any mistake is a usage error before anything moves."""
    names = names or []
    body, gripper = text, None
    match = _PREFIX.fullmatch(text)
    if match and match.group(1) not in DO_COMMANDS:
        gripper, body = match.group(1), match.group(2)
        if gripper not in names:
            known = ", ".join(names)
            raise UsageError(f"--do {text!r}: no gripper named {gripper!r} (the names are {known})")
    try:
        words = shlex.split(body)
    except ValueError as exc:  # "No closing quotation": the user's quoting, a usage error (exit 2)
        raise UsageError(f"--do {text!r}: {str(exc).lower()}") from None
    if not words or words[0] not in DO_COMMANDS:
        raise UsageError(f"--do {text!r}: expected one of {', '.join(DO_COMMANDS)}")
    if words[0] == "wait" and gripper is not None:
        raise UsageError(f"--do {text!r}: wait is for the whole recording, not for one gripper")
    try:
        args, rest = _do_parser(words[0]).parse_known_args(words[1:])
    except (argparse.ArgumentError, _DoError) as exc:
        raise UsageError(f"--do {text!r}: {exc}") from None
    if rest:
        raise UsageError(f"--do {text!r}: unrecognized {' '.join(rest)}")
    return Step(text, gripper, words[0], args)


# --- the run -----------------------------------------------------------------------------------------------


def _detail(result: Any) -> str | None:
    from .motion import result_dict

    plain = result_dict(result)
    if not plain:
        return None
    return " ".join(f"{k}={v}" for k, v in plain.items() if v is not None)


def _sleep(seconds: float, rec: Any) -> None:
    """Wait, in short steps: Ctrl-C ends it at once, and so does a recording that failed to write."""
    end = time.monotonic() + seconds
    while rec.error is None and (left := end - time.monotonic()) > 0:
        time.sleep(min(0.05, left))


def _ending(exc: BaseException) -> None:
    """After the first Ctrl-C (SIGTERM, SIGHUP) the command is ending: further signals are ignored, so they
    cut neither the stops, the file nor the closes short (each is bounded), nor turn the exit status into a
    death by signal (grippers/cli/signals.py). (A join interrupted by Ctrl-C can also take a running thread
    for ended: CPython's bpo-45274 handling.)"""
    if isinstance(exc, KeyboardInterrupt) and threading.current_thread() is threading.main_thread():
        signals.ending()


def _stop_all(grippers: dict[str, Any], names: list[str]) -> None:
    """Stop these grippers at once, each in its own thread, bounded."""

    def stop(name: str) -> None:
        try:
            grippers[name].stop()
        except Exception as exc:
            log.warning("%s: could not stop after the interrupt: %s", name, exc)

    threads = [threading.Thread(target=stop, args=(n,), name=f"grippers-record-stop-{n}") for n in names]
    for t in threads:
        t.start()
    deadline = time.monotonic() + STOP_BOUND  # signals are ignored by now (_ending): join is not interrupted
    for t in threads:
        t.join(max(0.0, deadline - time.monotonic()))


def run_step(step: Step, grippers: dict[str, Any], rec: Any) -> BaseException | None:
    """Run one --do command on its gripper(s), stamped; returns the first failure. The calls run in worker
    threads and this thread waits: on Ctrl-C (or any exception here) every gripper still busy is stopped
    before the exception leaves, so nothing runs on after the program ends."""
    from . import motion

    if step.name == "wait":
        rec.event(step.text, "start")
        _sleep(step.args.seconds, rec)
        rec.event(step.text, "done")
        return None
    names = [step.gripper] if step.gripper is not None else list(grippers)
    errors: dict[str, BaseException] = {}

    def work(name: str) -> None:
        rec.event(step.text, "start", gripper=name)
        try:
            result = getattr(motion, step.name).call(grippers[name], step.args)
        except Exception as exc:  # the recording goes on, with the error in it
            still_after_failure(grippers[name], exc)  # a failed motion leaves the jaws still (issue 39 §2)
            rec.event(step.text, "failed", str(exc), gripper=name)
            errors[name] = exc
            return
        rec.event(step.text, "done", _detail(result), gripper=name)

    # Events, not Thread.is_alive(): a join interrupted by Ctrl-C can mark a running thread stopped
    # (CPython's bpo-45274 handling), and that gripper would be left moving.
    ended = {n: threading.Event() for n in names}

    def worker(name: str) -> None:
        try:
            work(name)
        finally:
            ended[name].set()

    for n in names:
        threading.Thread(target=worker, args=(n,), name=f"grippers-record-{n}", daemon=True).start()
    try:
        for event in ended.values():
            while not event.wait(0.05):
                pass
    except BaseException as exc:
        _ending(exc)
        _stop_all(grippers, [n for n, e in ended.items() if not e.is_set()])
        deadline = time.monotonic() + STOP_BOUND  # their calls end "aborted by stop()", stamped "failed"
        for event in ended.values():
            event.wait(max(0.0, deadline - time.monotonic()))
        raise
    return next((errors[n] for n in names if n in errors), None)


def run(args: argparse.Namespace) -> int:
    from grippers.recorder import Recorder, names_of
    from grippers.recording import RecordingError, open_sink

    targets = named_targets(args.targets)
    plan = [parse_do(text, list(targets)) for text in args.do]
    try:
        sink = open_sink(args.output)  # a wrong name or an unwritable path is found before anything moves
    except RecordingError as exc:
        raise UsageError(str(exc)) from None
    grippers: dict[str, Any] = {}
    rec: Recorder | None = None
    failed: BaseException | None = None

    def finish(rec: Recorder) -> RecordingError | None:
        try:
            rec.close()  # finishes the file however many Ctrl-C come (bounded)
        except RecordingError as exc:
            return exc
        return None

    try:
        for name, url in targets.items():
            grippers[name] = open_gripper(argparse.Namespace(**{**vars(args), "target": url}))
        names_of(grippers)  # checked before the file gets its header
        header = {
            "target": " ".join(targets.values()),
            "grippers": [{"name": n, "target": u} for n, u in targets.items()],  # as typed
            "do": list(args.do),
        }
        rec = Recorder(args.output, grippers, rate_hz=args.rate, header=header, sink=sink)
        log.info("recording %s to %s (Ctrl-C ends it)", header["target"], ", ".join(rec.files))
        for step in plan:
            if rec.error is not None:
                break
            failed = run_step(step, grippers, rec)
            if failed is not None:
                break
        if args.duration is not None:
            _sleep(rec.start + args.duration - time.time(), rec)
        elif rec.error is None:
            _sleep(TAIL if plan else DEFAULT_DURATION, rec)
        failed = finish(rec) or failed  # a full disk, a file-size limit: the file named, its rows readable
    except BaseException as exc:
        _ending(exc)
        if rec is not None and (error := finish(rec)) is not None:
            print(error_line("record", error), file=sys.stderr)  # said; the first exception is raised
        raise
    finally:
        if rec is None:
            sink.abandon()
        for g in grippers.values():
            g.close()
    states, events = rec.states, rec.events
    if args.json:
        write_json(
            {
                "schema": RECORD_RESULT_SCHEMA_ID,
                "target": " ".join(targets.values()),
                "grippers": [{"name": n, "target": u} for n, u in targets.items()],
                "output": args.output,
                "format": rec.format,
                "files": rec.files,
                "states": states,
                "command_events": events,
                "failed": None if failed is None else " ".join(str(failed).split()),
            }
        )
    else:
        print(f"recorded {states} states and {events} command events to {', '.join(rec.files)}")
    if failed is not None:
        print(error_line("record", failed), file=sys.stderr)
        return EXIT_FAILED
    return EXIT_OK
