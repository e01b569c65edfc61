"""What the command line shows besides its results: the library's log lines and its warnings, on stderr.

Every subcommand takes ``-v`` (INFO: connections, reconnections, faults, lease changes), ``-vv`` (DEBUG, with
every frame and packet on the wire under the ``grippers.wire`` logger, in ``monitor``'s decoded form), ``-q``
(errors only) and ``--log-level LEVEL``. The default shows warnings only, so a plain command prints its result
and nothing else.

A :class:`grippers.GripperWarning` (an MSG's model assumed, ...) is printed as one line,
``grippers CMD: warning: TEXT``, whatever the level (a wrong width is worse than a noisy terminal), and kept
so the command's ``--json`` document lists it (:func:`issued_warnings`).

Kept free of heavy imports: ``grippers --help`` loads this module.
"""

from __future__ import annotations

import argparse
import sys
from typing import TYPE_CHECKING, Any, TextIO

if TYPE_CHECKING:  # logging costs ~20 ms to import: --help does without it
    import logging

LEVELS = ("debug", "info", "warning", "error")
LOG_FORMAT = "%(asctime)s %(levelname)s %(name)s: %(message)s"
_issued: list[str] = []
_saved: list[Any] = []  # warnings.showwarning as it was before setup(), put back by teardown()


def add_arguments(parser: argparse.ArgumentParser, *, suppress: bool) -> None:
    """``-v``/``-q``/``--log-level`` on ``parser``; ``suppress`` keeps a subcommand's default from overwriting
    what was given before the subcommand's name (``grippers -v state URL`` and ``grippers state -v URL``)."""
    default: dict[str, Any] = {"default": argparse.SUPPRESS} if suppress else {}
    parser.add_argument(
        "-v",
        "--verbose",
        action="count",
        help="more log lines on stderr: -v connections, faults (INFO); -vv every frame on the wire (DEBUG)",
        **({"default": argparse.SUPPRESS} if suppress else {"default": 0}),
    )
    parser.add_argument("-q", "--quiet", action="store_true", help="errors only on stderr", **default)
    parser.add_argument(
        "--log-level", choices=LEVELS, type=str.lower, help="log level for the grippers.* loggers", **default
    )


def level_for(args: argparse.Namespace) -> int:
    """--log-level wins; then -q; then each -v one step below WARNING."""
    import logging

    named = getattr(args, "log_level", None)
    if named:
        return int(getattr(logging, named.upper()))
    if getattr(args, "quiet", False):
        return logging.ERROR
    verbose = int(getattr(args, "verbose", 0) or 0)
    return {0: logging.WARNING, 1: logging.INFO}.get(verbose, logging.DEBUG)


def setup(args: argparse.Namespace, stream: TextIO | None = None) -> logging.Handler:
    """One handler on the ``grippers`` logger (not the root: other libraries' loggers stay as they are), with
    a time stamp, the level and the logger's name on each line; warnings routed as described above."""
    import logging

    level = level_for(args)
    handler = logging.StreamHandler(stream or sys.stderr)
    handler.setFormatter(logging.Formatter(LOG_FORMAT))
    logger = logging.getLogger("grippers")
    for old in list(logger.handlers):
        if getattr(old, "_grippers_cli", False):  # main() run twice in one process (tests)
            logger.removeHandler(old)
    handler._grippers_cli = True  # type: ignore[attr-defined]  # a marker; logging stays a lazy import here
    logger.addHandler(handler)
    logger.setLevel(level)
    logger.propagate = False
    _issued.clear()
    command = getattr(args, "command", None)
    _route_warnings(command)
    return handler


def _route_warnings(command: str | None) -> None:
    import warnings

    from grippers.errors import GripperWarning

    prefix = f"grippers {command}" if command else "grippers"
    if not _saved:
        _saved.append(warnings.showwarning)
    original = _saved[0]

    def show(message: Any, category: type[Warning], *rest: Any, **kw: Any) -> None:
        if not issubclass(category, GripperWarning):
            original(message, category, *rest, **kw)
            return
        text = " ".join(str(message).split())
        if text in _issued:  # probe opens many URLs; one line per distinct warning
            return
        _issued.append(text)
        print(f"{prefix}: warning: {text}", file=sys.stderr, flush=True)

    warnings.showwarning = show
    warnings.simplefilter("always", GripperWarning)  # the default "once per place" would drop repeats


def teardown(handler: logging.Handler) -> None:
    """Undo :func:`setup`: main() may run many times in one process (tests, programs that call it)."""
    import logging
    import warnings

    logging.getLogger("grippers").removeHandler(handler)
    if _saved:
        warnings.showwarning = _saved.pop()


def issued_warnings() -> list[str]:
    """The GripperWarnings this command printed so far, for the ``warnings`` field of its JSON document."""
    return list(_issued)
