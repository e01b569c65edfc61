"""``grippers sim FAMILY``: serve a simulated gripper of any installed family over a real transport.

The family's command hooks say what its simulator takes (issue 28 §2, issue 40 §2): ``sim_help``,
``sim_example`` and ``sim_names`` word the command; a family whose ``sim_command()`` gives an object
(``add_arguments(parser)``, ``run(args, backend)``) has its own options (a WSG's ``--firmware``, an MSG's CAN
nodes); the others get the common options over the backend's ``simulator(profile, settings, listen)``
(:class:`Generic`). The family is read first and its parser built then, so
``grippers --help`` loads no backend.
"""

from __future__ import annotations

import argparse
import sys
from typing import Any

HELP = "run a simulated gripper that speaks the real protocol (TCP, UDP, a pty or a CAN bus)"
EXAMPLE = (
    "grippers sim FAMILY --listen tcp://127.0.0.1:5020\n"
    "         grippers sim FAMILY --listen pty\n"
    "         grippers sim FAMILY --help   (what that family's simulator takes)"
)


def add_arguments(parser: argparse.ArgumentParser) -> None:
    from grippers.backends import BUILTIN_BACKENDS

    shown = ", ".join(f for f in BUILTIN_BACKENDS if f != "zenoh")
    parser.add_argument(
        "family",
        metavar="FAMILY",
        help=f"the family to simulate ({shown}, a name its simulator answers to, or an installed plugin's); "
        "`grippers sim FAMILY --help` lists its options",
    )
    parser.add_argument("family_args", nargs=argparse.REMAINDER, help=argparse.SUPPRESS)


class Generic:
    """The ``grippers sim`` of a family without a ``sim_command()``: a profile, where to listen, the clock
    and a part, passed to the backend's ``simulator(profile, settings, listen)``."""

    def __init__(self, family: str) -> None:
        self.family = family

    def add_arguments(self, parser: argparse.ArgumentParser) -> None:
        from .sim_common import add_sim_arguments

        add_sim_arguments(
            parser,
            None,
            "where to serve, as the family's simulator takes it (e.g. pty or tcp://HOST:PORT; default: the "
            "family's own)",
            replay=False,
        )

    def run(self, args: argparse.Namespace, backend: Any) -> int:
        from grippers.backends.command_hooks import commands_of
        from grippers.profiles import list_profiles, load_profile

        from .output import UsageError
        from .sim_common import serve_forever, settings_for, warn_private_bus

        if args.profile is None:
            default = commands_of(backend).default_profile or next(
                (p.name for p in list_profiles() if p.family == backend.family), None
            )
            if default is None:
                raise UsageError(f"the {self.family} family has no profile installed: --model NAME or a file")
            args.profile = default
        profile = load_profile(args.profile)
        if profile.family != backend.family:
            raise UsageError(f"profile {profile.name} is a {profile.family} profile, not a {self.family} one")
        warn_private_bus(args.listen or "")
        settings = settings_for(profile, args)
        try:
            server = backend.simulator(profile, settings, listen=args.listen)
        except ValueError as exc:  # a malformed --listen: the command line's fault
            raise UsageError(str(exc)) from None
        settings.finish()
        return serve_forever(server, f"simulated {profile.model}", as_json=args.json)


def _find(name: str) -> tuple[Any, Any]:
    """The backend simulating ``name`` (a family, or a name its ``sim_names`` declare, ``msg``) and its
    command (its ``sim_command()``, or :class:`Generic`)."""
    from grippers.backends import available_backends, find_backend
    from grippers.backends.command_hooks import commands_of

    from .output import UsageError

    backend = find_backend(name)
    if backend is None:
        for family in available_backends():
            try:
                other = find_backend(family)
            except Exception:  # a family whose optional dependency is missing has no simulator here
                continue
            if name in commands_of(other).sim_names:
                backend = other
                break
    if backend is None:
        raise UsageError(f"no family {name!r} to simulate (installed: {', '.join(available_backends())})")
    command = commands_of(backend).sim_command()
    if command is None:
        if not callable(getattr(backend, "simulator", None)):
            raise UsageError(f"the {backend.family} family offers no simulator")
        command = Generic(name)
    return backend, command


def family_parser(name: str) -> tuple[argparse.ArgumentParser, Any, Any]:
    """``grippers sim NAME``'s own parser (its help, options and example), its backend and its command."""
    from grippers.backends.command_hooks import commands_of

    from . import EXIT_CODES, _Parser, logs

    backend, command = _find(name)
    hooks = commands_of(backend)
    example = hooks.sim_example or f"grippers sim {name} --listen pty --model NAME"
    parser = _Parser(
        prog=f"grippers sim {name}",
        description=hooks.sim_help or f"simulate a {name} gripper with its backend's simulator",
        epilog=f"Example: {example}\n{EXIT_CODES}",
        formatter_class=argparse.RawDescriptionHelpFormatter,  # the examples, one per line
    )
    parser.add_argument("--debug", action="store_true", default=argparse.SUPPRESS, help="show tracebacks")
    logs.add_arguments(parser, suppress=True)
    command.add_arguments(parser)
    return parser, backend, command


def run(args: argparse.Namespace) -> int:
    from . import _unrecognized, logs

    parser, backend, command = family_parser(args.family)
    before = {k: getattr(args, k, None) for k in ("verbose", "quiet", "log_level")}
    family_args, unknown = parser.parse_known_args(args.family_args, namespace=args)
    if unknown:
        parser.error(_unrecognized(parser, unknown))
    handler = None
    if any(getattr(family_args, k, None) != v for k, v in before.items()):
        handler = logs.setup(family_args)  # -v given after the family: the log level it asks for
    try:
        return int(command.run(family_args, backend) or 0)
    finally:
        if handler is not None:
            logs.teardown(handler)
        sys.stdout.flush()
