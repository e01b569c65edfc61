"""Arguments shared by the subcommands, and opening the gripper they name.

The API objects become the CLI's documents in grippers/cli/output.py (:func:`~grippers.cli.output.state_dict`
and friends), which the recorder uses too. This module is imported by ``grippers --help``: the API is
imported inside the functions only (type names under TYPE_CHECKING), so start-up stays fast.
"""

from __future__ import annotations

import argparse
import math
from collections.abc import Iterator
from contextlib import contextmanager
from typing import TYPE_CHECKING, Any

from grippers.timeouts import DEFAULT_TIMEOUT_S

if TYPE_CHECKING:
    from grippers.gripper import Gripper

DEFAULT_TIMEOUT = DEFAULT_TIMEOUT_S  # seconds; per device for probe, per exchange otherwise


def positive_float(text: str) -> float:
    try:
        value = float(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"not a number: {text!r}") from None
    if not math.isfinite(value) or value <= 0:
        raise argparse.ArgumentTypeError(f"must be a positive number: {text!r}")
    return value


def non_negative_float(text: str) -> float:
    try:
        value = float(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"not a number: {text!r}") from None
    if not math.isfinite(value) or value < 0:
        raise argparse.ArgumentTypeError(f"must be zero or more: {text!r}")
    return value


def can_id(text: str) -> int:
    """An argparse type for a CAN identifier in decimal or 0x hex (``--can-id`` of probe and monitor)."""
    try:
        value = int(text, 0)
    except ValueError:
        raise argparse.ArgumentTypeError(f"not an integer: {text!r}") from None
    if not 0 <= value <= 0x7FF:  # 11-bit identifiers: 0x7FF is a valid one
        raise argparse.ArgumentTypeError(f"not a standard (11-bit) CAN id 0..0x7FF: {text!r}")
    return value


def add_target(parser: argparse.ArgumentParser) -> None:
    parser.add_argument(
        "target",
        metavar="URL",
        help="a connection URL (FAMILY+tcp://HOST[:PORT], FAMILY+udp://, FAMILY+serial://PORT, "
        "FAMILY+can://IF/CH[?node=N], sim://PROFILE, zenoh://NAME; grippers probe finds them), a profile "
        "name or a profile file",
    )


def add_can_flags(parser: argparse.ArgumentParser) -> None:
    """The flags python-can's own tools use, with the same short names."""
    parser.add_argument(
        "-i", "--interface", help="python-can interface (socketcan, udp_multicast, virtual, ...)"
    )
    parser.add_argument("-c", "--channel", help="python-can channel (can0, a multicast group, ...)")
    parser.add_argument("-b", "--bitrate", type=int, help="CAN bitrate in bit/s")


def add_common(
    parser: argparse.ArgumentParser, json_help: str = "print JSON (schema in docs/cli.md)"
) -> None:
    parser.add_argument(
        "-t",
        "--timeout",
        type=positive_float,
        default=DEFAULT_TIMEOUT,
        metavar="SECONDS",
        help=f"give up on an exchange after this long without an answer (default {DEFAULT_TIMEOUT:g})",
    )
    parser.add_argument("--json", action="store_true", help=json_help)
    parser.add_argument(
        "--profile", metavar="NAME", help="device profile, for devices that cannot report their model"
    )
    add_can_flags(parser)


def overrides_from(args: argparse.Namespace) -> dict[str, Any]:
    """Keyword overrides for :func:`grippers.open` from the flags the user actually gave."""
    out: dict[str, Any] = {}
    for name in ("interface", "channel", "bitrate", "profile"):
        value = getattr(args, name, None)
        if value is not None:
            out[name] = value
    return out


def open_gripper(args: argparse.Namespace) -> Gripper:
    """Open the gripper named on the command line; a malformed URL or unknown profile is a usage error."""
    import grippers
    from grippers.errors import ProfileError, URLError

    from .suggest import hint

    kwargs = overrides_from(args)
    timeout = getattr(args, "timeout", None)
    if timeout is not None:
        kwargs["timeout"] = timeout
    try:
        return grippers.open(args.target, **kwargs)
    except (URLError, ProfileError) as exc:
        fix = hint(args.target)
        if fix is None:
            raise
        raise type(exc)(f"{exc.message} ({fix})", device=exc.device, command=exc.command) from exc


def stop_running_motions(gripper: Gripper, by: str) -> list[BaseException]:
    """Stop (bounded) every motion of ``gripper`` that still runs, as Ctrl-C in a blocking call does; returns
    the stops that failed. Sends nothing when no motion runs (an MSG over UART stop switches the motor off, so
    a held part would be let go).

    Why here: the library stops a motion on Ctrl-C only inside a blocking call; a motion started with
    ``wait=False`` belongs to its caller, and ``close()`` lets it run on to its end (documented), so a
    command that is interrupted while it polls (``selftest``'s timed moves) left the jaws moving after exit
    130 (issue 33 §1). Each motion ends with CommandFailed "aborted by BY"."""
    return gripper.async_support().stop_running_motions(by)


@contextmanager
def stops_motions_on_error(gripper: Gripper) -> Iterator[Gripper]:
    """``with stops_motions_on_error(gripper):``: whatever leaves the block early (Ctrl-C, SIGTERM, SIGHUP
    first of all, or an error of the command's own) stops the motions still running before it propagates; a
    block that ends normally leaves them alone (a command may mean to leave a motion running).

    For commands that start motions without waiting (``selftest``; ``record --do``, ``serve`` and the ROS node
    may use it too). A failed stop is added to the exception as a note; a second Ctrl-C during the stop ends
    the wait for it (grippers/motions.py), never the exit."""
    from .signals import signal_name

    try:
        yield gripper
    except BaseException as exc:
        by = signal_name(exc)
        for failure in stop_running_motions(gripper, by):
            exc.add_note(f"{gripper.name}: stopping the gripper after {by} failed: {failure}")
        raise


def still_after_failure(gripper: Gripper, exc: BaseException) -> None:
    """A motion the command line asked for failed (its ``--motion-timeout`` ran out, the device refused, the
    link broke): stop the device, so the jaws are still when the command says "failed" (issue 39 §2).

    Why not only the library's own stop: a motion's own timeout ends the call but not the device's motion
    on every family (an MSG or a Robotiq went on to its target after exit 1), and the next command line is
    a new process that cannot know. Not after a usage error (nothing was sent: an MSG over UART would let a
    held part go on a needless stop) nor after Ctrl-C and the signals, which the library stopped already. A
    failed stop is added to ``exc`` as a note."""
    from . import _is_usage_error

    if not isinstance(exc, Exception) or _is_usage_error(exc):
        return
    try:
        gripper.stop()
    except Exception as failure:
        exc.add_note(f"{gripper.name}: stopping the gripper after the failure failed too: {failure}")


@contextmanager
def stills_on_failure(gripper: Gripper) -> Iterator[Gripper]:
    """``with stills_on_failure(gripper): gripper.move(...)``: :func:`still_after_failure` on an error."""
    try:
        yield gripper
    except BaseException as exc:
        still_after_failure(gripper, exc)
        raise


@contextmanager
def opened_gripper(args: argparse.Namespace) -> Iterator[Gripper]:
    """:func:`open_gripper` for a ``with`` block: closed at the end, and its running motions stopped first
    when the block is left by Ctrl-C or an error (:func:`stops_motions_on_error`)."""
    gripper = open_gripper(args)
    try:
        with stops_motions_on_error(gripper):
            yield gripper
    finally:
        gripper.close()
