"""How a command ends on a signal: the CLI's one rule for SIGINT, SIGTERM and SIGHUP (docs/cli.md).

Ctrl-C already stopped the jaws and finished the files: the library stops a motion before KeyboardInterrupt
leaves a blocking call, :func:`grippers.cli.common.stops_motions_on_error` stops motions started without
waiting, and the recorder finishes its file on it. SIGTERM (``kill``, a service manager) and SIGHUP (a closed
terminal or ssh session, the commonest end of a bench session) took the default action instead: the process
died at once and the jaws moved on (issue 43 §1). Here both raise :class:`Terminated`, a KeyboardInterrupt
raised where Ctrl-C's would be, so every path written for Ctrl-C serves them too, and nothing has two rules.

A command interrupted this way exits ``128 + n`` (130, 143, 129), the shells' convention. A signal the
process inherited as ignored (``nohup grippers ...``) stays ignored. Servers (``sim``, ``serve``) take SIGTERM
and SIGHUP as their ordinary end and exit 0 after the same stops.

Once the command has returned, a late signal (Ctrl-C 50 ms after the summary) must not turn a finished
command into an interrupted one or print a traceback from the interpreter's shutdown: :func:`finished`
makes it end the process at once with the command's own status.
"""

from __future__ import annotations

import os
import signal
import sys
from collections.abc import Callable
from types import FrameType

CAUGHT = (signal.SIGINT, signal.SIGTERM, signal.SIGHUP)
_Handler = Callable[[int, FrameType | None], object] | int | signal.Handlers | None


class Terminated(KeyboardInterrupt):
    """SIGTERM or SIGHUP, raised in the main thread as Ctrl-C's KeyboardInterrupt is (the same stops)."""

    def __init__(self, signum: int) -> None:
        super().__init__(signal.Signals(signum).name)
        self.signum = signum


def _raise(signum: int, frame: FrameType | None) -> None:
    if signum == signal.SIGINT:
        raise KeyboardInterrupt
    raise Terminated(signum)


def signal_name(exc: BaseException) -> str:
    """``Ctrl-C``, ``SIGTERM`` or ``SIGHUP``: what ended a command, for its messages."""
    if isinstance(exc, Terminated):
        return signal.Signals(exc.signum).name
    return "Ctrl-C"


def exit_status(exc: KeyboardInterrupt) -> int:
    """128 + the signal's number: 130 for Ctrl-C, 143 for SIGTERM, 129 for SIGHUP."""
    return 128 + (exc.signum if isinstance(exc, Terminated) else signal.SIGINT)


def _install(handler: _Handler) -> dict[int, _Handler]:
    """``handler`` for every caught signal the process does not ignore; returns what to put back. Only the
    main thread may set handlers: elsewhere (a command run from a test's thread) nothing changes."""
    import threading

    previous: dict[int, _Handler] = {}
    if threading.current_thread() is not threading.main_thread():
        return previous
    for sig in CAUGHT:
        current = signal.getsignal(sig)
        if current is signal.SIG_IGN:  # nohup, or a parent that wants this process to outlive it
            continue
        previous[sig] = signal.signal(sig, handler)
    return previous


def like_ctrl_c() -> dict[int, _Handler]:
    """From now on SIGINT, SIGTERM and SIGHUP raise KeyboardInterrupt (:class:`Terminated`); returns the
    handlers to put back with :func:`restore`."""
    return _install(_raise)


def restore(previous: dict[int, _Handler]) -> None:
    """Put back the handlers :func:`like_ctrl_c` replaced (a command run in-process, as the tests do)."""
    for sig, handler in previous.items():
        signal.signal(sig, handler)


def ends_service(handler: Callable[[int, FrameType | None], object]) -> dict[int, _Handler]:
    """A server's ordinary end (``sim``, ``serve``, ``ros2``): ``handler`` for SIGTERM and SIGHUP (a service
    manager, a closed terminal), which stops the jaws and exits 0; Ctrl-C stays KeyboardInterrupt (130).
    Returns the handlers to put back with :func:`restore`."""
    previous = _install(handler)
    if signal.SIGINT in previous:  # Ctrl-C keeps the rule of every command
        signal.signal(signal.SIGINT, previous.pop(signal.SIGINT))
    return previous


def ending() -> None:
    """The command is ending after a signal: the ones that follow are ignored, so they cut neither the stops,
    the files nor the closes short (each is bounded), nor turn the exit status into a death by signal."""
    _install(signal.SIG_IGN)


def finished(status: int) -> None:
    """The command has returned ``status``: a signal from now on ends the process at once with that status,
    instead of a traceback from the interpreter's shutdown (threading's join of the last threads)."""

    def exit_now(signum: int, frame: FrameType | None) -> None:
        for stream in (sys.stdout, sys.stderr):
            try:
                stream.flush()
            except Exception:  # a flush this handler interrupted: what it held is lost either way
                pass
        os._exit(status)

    for stream in (sys.stdout, sys.stderr):
        try:
            stream.flush()
        except Exception:  # a closed pipe: nothing more reaches it
            pass
    _install(exit_now)
