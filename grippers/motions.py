"""Motion handles: one motion's outcome, settled once, whichever thread decides it.

A motion ends in one of three ways: the backend's call returns or raises (the device's own outcome), or the
motion is ended early in this process (a newer motion supersedes it; ``stop()``, ``fast_stop()``,
``cancel()`` or Ctrl-C aborts it). The first to settle the handle wins, so a handle can never report the
result of a motion that was sent after it: an aborted motion's backend call may still return a width or
a detection value, but by then it describes another command's work and is discarded.

The rule the :class:`~grippers.gripper.Gripper` applies, the same for every family (README "Motions"):

* a motion started while another runs **supersedes** it: the older call or ``wait()`` raises
  :class:`CommandFailed` "superseded by …" at once, the device is stopped (the WSG refuses a new motion
  while one runs, E_ALREADY_RUNNING, WSG manual 4.0.x §3.2.2) and the newer motion is sent once the older
  call has ended;
* ``stop()``, ``fast_stop()``, ``cancel()`` and Ctrl-C make the running motion raise
  :class:`CommandFailed` "aborted by …".
"""

from __future__ import annotations

import logging
import math
import threading
from collections.abc import Callable
from typing import Any, Generic, TypeVar

from .errors import CommandFailed, GripperTimeout, LimitError

T = TypeVar("T")

log = logging.getLogger(__name__)


def wait_seconds(timeout: Any, command: str, device: str | None = None) -> float | None:
    """A timeout a wait can use: None (no bound) or a number of seconds, at most ``threading.TIMEOUT_MAX``.

    ``Event.wait(1e10)`` raises OverflowError and ``nan`` would wait forever; both are the caller's mistake
    and get a :class:`LimitError` naming the command.
    """
    if timeout is None:
        return None
    try:
        seconds = float(timeout)
    except (TypeError, ValueError, OverflowError):
        raise LimitError(
            f"timeout must be a number of seconds, not {timeout!r}", device=device, command=command
        ) from None
    if math.isnan(seconds) or seconds < 0:
        raise LimitError(
            f"timeout must be 0 or more seconds, not {timeout!r}", device=device, command=command
        )
    return min(seconds, threading.TIMEOUT_MAX)


class MotionHandle(Generic[T]):
    """A motion started with ``wait=False``: poll ``done()``, ``wait()`` for the result, or ``cancel()``.

    ``wait()`` raises what the motion raised: :class:`CommandFailed` "superseded by …" when a newer motion
    replaced it, "aborted by …" when ``stop()``, ``fast_stop()`` or ``cancel()`` ended it first.
    """

    def __init__(
        self,
        name: str,
        run: Callable[[], T] | None = None,
        cancel: Callable[[], None] | None = None,
        *,
        device: str | None = None,
    ) -> None:
        self.name = name
        self.device = device
        self._cancel = cancel
        self._lock = threading.Lock()
        self._done = threading.Event()
        self._result: T | None = None
        self._error: BaseException | None = None
        self._abort: CommandFailed | None = None  # set once by whoever ends the motion early
        self._callbacks: list[Callable[[MotionHandle[T]], Any]] = []
        self._thread: threading.Thread | None = None
        if run is not None:
            self._start(run)

    # -- the side that runs and ends motions (the Gripper) ---------------------------------------------

    def _start(self, run: Callable[[], T]) -> None:
        self._thread = threading.Thread(
            target=self._run, args=(run,), name=f"grippers-{self.name}", daemon=True
        )
        self._thread.start()

    def _run(self, run: Callable[[], T]) -> None:
        try:
            result = run()
        except BaseException as exc:  # handed to whoever waits
            self._settle(None, exc)
        else:
            self._settle(result, None)

    def _settle(self, result: T | None, error: BaseException | None) -> bool:
        """Decide the outcome once; an abort marked earlier wins over what the backend returned."""
        with self._lock:
            if self._done.is_set():
                return False
            if self._abort is not None:
                if error is not None and error is not self._abort and self._abort.__cause__ is None:
                    self._abort.__cause__ = error  # the device's own words stay reachable
                result, error = None, self._abort
            self._result, self._error = result, error
            self._done.set()
            callbacks, self._callbacks = self._callbacks, []
        for fn in callbacks:
            self._call(fn)
        return True

    def _mark_aborted(self, error: CommandFailed) -> bool:
        """Record why the motion ended early; False when it had already ended (nothing to abort)."""
        with self._lock:
            if self._done.is_set() or self._abort is not None:
                return False
            self._abort = error
            return True

    def _settle_aborted(self) -> None:
        if self._abort is not None:
            self._settle(None, self._abort)

    def _ended(self) -> bool:
        """Done, or marked to end: nothing more may be sent for it."""
        return self._done.is_set() or self._abort is not None

    def _busy(self) -> bool:
        """Its backend call still runs (even when the handle has been settled as superseded)."""
        return self._thread is not None and self._thread.is_alive()

    def _call(self, fn: Callable[[MotionHandle[T]], Any]) -> None:
        try:
            fn(self)
        except Exception:  # one broken callback must not keep the others (or the motion thread) from running
            log.exception("a motion handle's done callback raised")

    # -- the user's side -----------------------------------------------------------------------------

    def done(self) -> bool:
        return self._done.is_set()

    def wait(self, timeout: float | None = None) -> T:
        """The motion's result; re-raises its error; GripperTimeout if still running after ``timeout``.

        ``None`` waits until the motion ends, which its own timeout bounds. Interrupting ``wait()`` (Ctrl-C)
        does not stop the motion: ``cancel()`` does.
        """
        seconds = wait_seconds(timeout, self.name, self.device)
        if not self._done.wait(seconds):
            raise GripperTimeout(f"still running after {timeout:g} s", device=self.device, command=self.name)
        if self._error is not None:
            raise self._error
        return self._result  # type: ignore[return-value]

    def cancel(self) -> None:
        """Stop the motion on the device; ``wait()`` then raises CommandFailed "aborted by cancel()"."""
        if not self.done() and self._cancel is not None:
            self._cancel()

    def add_done_callback(self, fn: Callable[[MotionHandle[T]], Any]) -> None:
        """Call ``fn(handle)`` once when the motion ends, from the thread that ends it (the motion's own
        thread, or the one calling stop(), cancel() or starting a newer motion), or at once, here, if it has
        already ended. ``fn`` may call ``wait(0)``; exceptions it raises are logged."""
        with self._lock:
            if not self._done.is_set():
                self._callbacks.append(fn)
                return
        self._call(fn)

    def join(self, timeout: float) -> None:
        """Wait (bounded) until the backend call behind this motion has returned, not only its outcome."""
        if self._thread is not None and self._thread is not threading.current_thread():
            self._thread.join(wait_seconds(timeout, self.name, self.device))

    def __repr__(self) -> str:
        state = "done" if self.done() else "running"
        return f"<MotionHandle {self.name} {state}>"
