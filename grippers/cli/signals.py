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

CPython swallows an exception raised in a weakref callback, a ``__del__`` or a garbage-collector callback (it
reports it to :data:`sys.unraisablehook` and goes on). A signal whose handler ran there, such as the import
system's module-lock callback in the first milliseconds of a command, was lost: the command ran on (issue 43).
While the rule is in place, :func:`_resend_swallowed` sends such a signal again, so it lands in the command's
own code and ends it like any other.

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
from typing import Any

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


_previous_hook: Callable[[Any], object] | None = None  # sys.unraisablehook before like_ctrl_c()


def _resend_swallowed(unraisable: Any) -> None:
    """``sys.unraisablehook`` while the rule holds: a KeyboardInterrupt of ours that CPython swallowed
    (raised in a weakref callback or a ``__del__``) is sent again from another thread, so that the main
    thread takes it at its next step in ordinary code; anything else goes to the hook that was there
    before."""
    exc = unraisable.exc_value
    if not isinstance(exc, KeyboardInterrupt) or signal.getsignal(_signum(exc)) is not _raise:
        (_previous_hook or sys.__unraisablehook__)(unraisable)
        return
    import threading

    # Sent 10 ms later, so that it lands after this hook has returned (a signal that came in here, while the
    # timer's thread starts, would be lost for good): the same signal comes again.
    again = threading.Timer(0.01, os.kill, (os.getpid(), _signum(exc)))
    again.daemon = True
    try:
        again.start()
    except KeyboardInterrupt as late:  # a second signal, during the start
        _resend_swallowed(type("Unraisable", (), {"exc_value": late})())


def _signum(exc: KeyboardInterrupt) -> int:
    return exc.signum if isinstance(exc, Terminated) else signal.SIGINT


def signal_name(exc: BaseException) -> str:
    """``Ctrl-C``, ``SIGTERM`` or ``SIGHUP`` for a KeyboardInterrupt, else the exception's type: what ended a
    command or a motion, for its messages (one rule: :func:`grippers.motions.stopped_by`)."""
    from grippers.motions import stopped_by

    return stopped_by(exc)


def exit_status(exc: KeyboardInterrupt) -> int:
    """128 + the signal's number: 130 for Ctrl-C, 143 for SIGTERM, 129 for SIGHUP."""
    return 128 + _signum(exc)


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
    handlers to put back with :func:`restore`. A signal CPython swallows is sent again
    (:func:`_resend_swallowed`)."""
    global _previous_hook
    previous = _install(_raise)
    if previous and sys.unraisablehook is not _resend_swallowed:
        _previous_hook, sys.unraisablehook = sys.unraisablehook, _resend_swallowed
    return previous


def restore(previous: dict[int, _Handler]) -> None:
    """Put back the handlers :func:`like_ctrl_c` replaced (a command run in-process, as the tests do)."""
    global _previous_hook
    for sig, handler in previous.items():
        signal.signal(sig, handler)
    if sys.unraisablehook is _resend_swallowed and _previous_hook is not None:
        sys.unraisablehook, _previous_hook = _previous_hook, None


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
