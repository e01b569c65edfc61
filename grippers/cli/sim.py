"""``grippers sim FAMILY``: serve a simulated gripper of any installed family over a real transport.

The family's backend says what its simulator takes (issue 28 §2): a backend with a ``cli_sim`` object (its
``HELP``, ``EXAMPLE``, ``NAMES``, ``add_arguments(parser)`` and ``run(args, backend)``) has its own options
(a WSG's ``--firmware``, an MSG's CAN nodes); a backend with only ``simulator(profile, settings, listen)``
gets the common options (:class:`Generic`). The family is read first and its parser built then, so
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
    """The ``grippers sim`` of a family that declares no ``cli_sim``: a profile, where to listen, the clock
    and a part, passed to the backend's ``simulator(profile, settings, listen)``."""

    NAMES: tuple[str, ...] = ()

    def __init__(self, family: str, backend: Any) -> None:
        from grippers.backends import hook

        self.family = family
        self.HELP = hook(backend, "sim_help") or f"simulate a {family} gripper with its backend's simulator"
        self.EXAMPLE = hook(backend, "sim_example") or f"grippers sim {family} --listen pty --model NAME"

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
        from grippers.backends import hook
        from grippers.profiles import list_profiles, load_profile

        from .output import UsageError
        from .sim_common import serve_forever, settings_for, warn_private_bus

        if args.profile is None:
            default = hook(backend, "default_profile") or next(
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
    """The backend simulating ``name`` (a family, or a name its ``cli_sim`` declares, ``msg``) and its
    command (its ``cli_sim``, or :class:`Generic`)."""
    from grippers.backends import available_backends, find_backend, hook

    from .output import UsageError

    backend = find_backend(name)
    if backend is None:
        for family in available_backends():
            try:
                other = find_backend(family)
            except Exception:  # a family whose optional dependency is missing has no simulator here
                continue
            if name in getattr(hook(other, "cli_sim"), "NAMES", ()):
                backend = other
                break
    if backend is None:
        raise UsageError(f"no family {name!r} to simulate (installed: {', '.join(available_backends())})")
    command = hook(backend, "cli_sim")
    if command is None:
        if not callable(getattr(backend, "simulator", None)):
            raise UsageError(f"the {backend.family} family offers no simulator")
        command = Generic(name, backend)
    return backend, command


def family_parser(name: str) -> tuple[argparse.ArgumentParser, Any, Any]:
    """``grippers sim NAME``'s own parser (its help, options and example), its backend and its command."""
    from . import EXIT_CODES, _Parser, logs

    backend, command = _find(name)
    parser = _Parser(
        prog=f"grippers sim {name}",
        description=command.HELP,
        epilog=f"Example: {command.EXAMPLE}\n{EXIT_CODES}",
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
