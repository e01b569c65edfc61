"""The ``grippers`` command line.

Each subcommand is a module (or an object in a module, ``".motion:home"``) exposing ``HELP`` (one line),
``EXAMPLE``, ``add_arguments(parser)`` and ``run(args) -> int``. Modules import heavy things (python-can,
pydantic, drivers) inside ``run`` only, so ``grippers --help`` stays fast.

Exit codes (docs/cli.md): 0 success, 1 the device failed / nothing answered, 2 usage error, 130 interrupted
(143 SIGTERM, 129 SIGHUP: grippers/cli/signals.py).
Errors end in one line on stderr; ``--debug`` shows the traceback instead.
"""

from __future__ import annotations

import argparse
import importlib
import os
import sys
from collections.abc import Sequence
from typing import Any

from . import logs, signals

# name -> module (relative to this package) or "module:attribute"; order is the order shown in --help.
SUBCOMMANDS: dict[str, str] = {
    "probe": ".probe",
    "state": ".state",
    "info": ".info",
    "home": ".motion:home",
    "move": ".motion:move",
    "grasp": ".motion:grasp",
    "release": ".motion:release",
    "stop": ".motion:stop",
    "ack": ".motion:ack",
    "settings": ".settings_cmd",
    "selftest": ".selftest",
    "record": ".record",
    "plot": ".plot",
    "profiles": ".profiles_cmd",
    "monitor": ".monitor",
    "sim": ".sim",
    "doctor": ".doctor",
    "serve": ".serve",
    "panel": ".panel",
    "ros2": ".ros2_cmd",
}


def _load(spec: str) -> Any:
    module_name, _, attribute = spec.partition(":")
    module = importlib.import_module(module_name, __name__)
    return getattr(module, attribute) if attribute else module


class _Parser(argparse.ArgumentParser):
    """argparse with errors on one line (the CLI's rule for every error), still exit code 2."""

    def error(self, message: str) -> Any:
        self.exit(2, f"{self.prog}: error: {message} (see {self.prog} --help)\n")


class _VersionAction(argparse.Action):
    """``--version``: the one source of the version, grippers/_version.py (pyproject.toml reads it too)."""

    def __call__(self, parser: argparse.ArgumentParser, *_: Any) -> None:
        from grippers._version import __version__

        print(f"grippers {__version__}")
        parser.exit(0)


EXIT_CODES = (
    "Exit codes: 0 ok, 1 failed or nothing found, 2 usage error, 130 interrupted (Ctrl-C), "
    "143 SIGTERM, 129 SIGHUP."
)


def build_parser() -> argparse.ArgumentParser:
    parser = _Parser(
        prog="grippers",
        description="Drive robot grippers of every installed family, and their simulators.",
        epilog=f"Example: grippers probe sim://\n{EXIT_CODES}",
        formatter_class=argparse.RawDescriptionHelpFormatter,
    )
    parser.add_argument("--debug", action="store_true", help="show tracebacks on errors")
    parser.add_argument("--version", action=_VersionAction, nargs=0, help="print the version and exit")
    logs.add_arguments(parser, suppress=False)
    sub = parser.add_subparsers(dest="command", metavar="COMMAND")
    for name, spec in SUBCOMMANDS.items():
        command = _load(spec)
        sp = sub.add_parser(
            name,
            help=command.HELP,
            description=command.HELP,
            epilog=f"Example: {command.EXAMPLE}\n{EXIT_CODES}",
            formatter_class=argparse.RawDescriptionHelpFormatter,
        )
        sp.add_argument("--debug", action="store_true", default=argparse.SUPPRESS, help="show tracebacks")
        logs.add_arguments(sp, suppress=True)
        command.add_arguments(sp)
        sp.set_defaults(_module=command)
    return parser


def main(argv: Sequence[str] | None = None) -> int:
    """The ``grippers`` command; returns its exit code (docs/cli.md).

    Ctrl-C anywhere in here is exit 130 and one line: while the subcommands' modules load and the arguments
    are parsed (the first ~50 ms, issue 33 §3: a traceback and exit -2 before), during the command, and while
    it cleans up. Only what runs before this function cannot be covered: the interpreter's own start-up and
    the import of ``grippers`` and ``grippers.cli`` (module-level imports kept small for that reason too).
    The library stops a moving gripper before KeyboardInterrupt leaves a blocking call, and commands that
    start motions without waiting stop them themselves (:func:`grippers.cli.common.stops_motions_on_error`).

    SIGTERM and SIGHUP take the same path (grippers/cli/signals.py: one rule for every command, issue 43 §1)
    and exit 143 and 129. Called as the program (``argv`` None), a signal after the command has returned
    ends the process with the command's own status; called with ``argv`` (tests, scripts), the signal
    handlers are put back instead.
    """
    previous = signals.like_ctrl_c()
    command: list[str] = []  # the subcommand, once parsed, for the one line
    try:
        status = _main(argv, command)
    except KeyboardInterrupt as exc:
        signals.ending()  # a second Ctrl-C neither cuts the line short nor changes the status
        status = signals.exit_status(exc)
        how = "" if not isinstance(exc, signals.Terminated) else f" by {signals.signal_name(exc)}"
        try:
            print(f"grippers{''.join(' ' + c for c in command)}: interrupted{how}", file=sys.stderr)
        except KeyboardInterrupt:  # a signal the process ignored before ours: the exit code still says it
            pass
    finally:
        if argv is not None:  # also after argparse's SystemExit: a caller's handlers are its own again
            signals.restore(previous)
    if argv is None:
        signals.finished(status)
    return status


def _main(argv: Sequence[str] | None, command: list[str]) -> int:
    parser = build_parser()
    args, unknown = parser.parse_known_args(argv)  # exits 2 on usage errors, with argparse's message
    module = getattr(args, "_module", None)
    if module is None:
        if unknown:
            parser.error(_unrecognized(parser, unknown))
        parser.print_help()
        return 2
    command.append(args.command)
    if unknown:  # the subcommand names the mistake and its own --help, not the top-level parser
        command_parser = _subparsers(parser)[args.command]
        command_parser.error(_unrecognized(command_parser, unknown))
    from .output import EXIT_FAILED, EXIT_OK, EXIT_USAGE, UsageError, error_line

    handler = logs.setup(args)
    try:
        return int(module.run(args) or 0)
    except BrokenPipeError:  # `grippers monitor ... | head`: not an error; keep Python quiet at exit
        devnull = os.open(os.devnull, os.O_WRONLY)
        os.dup2(devnull, sys.stdout.fileno())
        return EXIT_OK
    except Exception as exc:  # one line on stderr unless --debug
        if getattr(args, "debug", False):
            raise
        print(error_line(args.command, exc), file=sys.stderr)
        if isinstance(exc, UsageError) or _is_usage_error(exc):
            return EXIT_USAGE
        return EXIT_FAILED
    finally:
        logs.teardown(handler)


def _subparsers(parser: argparse.ArgumentParser) -> dict[str, argparse.ArgumentParser]:
    for action in parser._actions:
        if isinstance(action, argparse._SubParsersAction):
            return dict(action.choices)
    return {}


def _unrecognized(parser: argparse.ArgumentParser, unknown: list[str]) -> str:
    """``unrecognized --forse; did you mean --force?``: this command's nearest option, if one is close."""
    import difflib

    options = [o for action in parser._actions for o in action.option_strings if o.startswith("--")]
    first = next((u for u in unknown if u.startswith("-")), unknown[0])
    close = difflib.get_close_matches(first.split("=", 1)[0], options, n=1, cutoff=0.75)
    hint = f"; did you mean {close[0]}?" if close else ""
    return f"unrecognized {' '.join(unknown)}{hint}"


def _is_usage_error(exc: BaseException) -> bool:
    """Errors that mean 'the command line was wrong': a malformed URL or unknown setting (URLError), an
    unknown or invalid profile (ProfileError), a value outside the gripper's limits (LimitError)."""
    from grippers.errors import LimitError, ProfileError, URLError

    return isinstance(exc, URLError | ProfileError | LimitError)


if __name__ == "__main__":  # pragma: no cover
    sys.exit(main())
