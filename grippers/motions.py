"""Motion handles (one motion's outcome, settled once, whichever thread decides it) and the supervisor that
applies the one rule for motions to a gripper.

A motion ends in one of three ways: the backend's call returns or raises (the device's own outcome), or the
motion is ended early in this process (a newer motion supersedes it; ``stop()``, ``fast_stop()``,
``cancel()`` or Ctrl-C aborts it). The first to settle the handle wins, so a handle can never report the
result of a motion that was sent after it: an aborted motion's backend call may still return a width or
a detection value, but by then it describes another command's work and is discarded.

The rule the :class:`~grippers.gripper.Gripper` applies, the same for every family (README, "Motions end
honestly"):

* a motion started while another runs **supersedes** it: the older call or ``wait()`` raises
  :class:`CommandFailed` "superseded by …" at once, the device is stopped (the WSG refuses a new motion
  while one runs, E_ALREADY_RUNNING, WSG manual 4.0.x §3.2.2) and the newer motion is sent once the older
  call has ended;
* ``stop()``, ``fast_stop()`` and ``cancel()`` make the running motion raise :class:`CommandFailed`
  "aborted by …";
* Ctrl-C (any exception) in a blocking motion call stops the gripper (bounded) before the exception leaves
  the call.

Errors a backend raises for ends it detects on the device (a stop from another program, an e-stop) pass
through unchanged; when this process ended the motion, its "superseded"/"aborted" error wins and the
backend's error becomes its ``__cause__``.
"""

from __future__ import annotations

import logging
import math
import threading
import time
from collections.abc import Callable
from typing import Any, Generic, TypeVar, cast

from grippers.drivers.numbers import is_text

from .errors import CommandFailed, GripperError, GripperTimeout, LimitError

T = TypeVar("T")

log = logging.getLogger(__name__)


def wait_seconds(timeout: Any, command: str, device: str | None = None) -> float | None:
    """A timeout a wait can use: None (no bound) or a number of seconds, at most ``threading.TIMEOUT_MAX``.

    ``Event.wait(1e10)`` raises OverflowError and ``nan`` would wait forever; both are the caller's mistake
    and get a :class:`LimitError` naming the command.
    """
    if timeout is None:
        return None
    if isinstance(timeout, bool) or is_text(timeout):  # the one rule for numbers (drivers/numbers.py)
        raise LimitError(
            f"timeout must be a number of seconds, not {timeout!r}", device=device, command=command
        )
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


# Starts ``body`` (named, for thread names) somewhere it may block until the motion ends.
Spawn = Callable[[Callable[[], None], str], None]


def _thread_of_its_own(body: Callable[[], None], name: str) -> None:
    threading.Thread(target=body, name=name, daemon=True).start()


def stopped_by(exc: BaseException) -> str:
    """What ended a motion, for its "aborted by ..." message: ``Ctrl-C``, the signal's name for a
    KeyboardInterrupt that carries one (the CLI raises SIGTERM and SIGHUP as ``KeyboardInterrupt("SIGTERM")``,
    grippers/cli/signals.py), else the exception's type."""
    if isinstance(exc, KeyboardInterrupt):
        named = exc.args[0] if exc.args and isinstance(exc.args[0], str) else ""
        return named if named.startswith("SIG") and named.isalnum() else "Ctrl-C"
    return type(exc).__name__


class MotionHandle(Generic[T]):
    """A motion started with ``wait=False``: poll ``done()``, ``wait()`` for the result, or ``cancel()``.

    ``wait()`` raises what the motion raised: :class:`CommandFailed` "superseded by …" when a newer motion
    replaced it, "aborted by …" when ``stop()``, ``fast_stop()`` or ``cancel()`` ended it first.
    """

    def __init__(
        self,
        name: str,
        run: Callable[[], T] | None = None,
        cancel: Callable[[], object] | None = None,
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
        self._submitted = False
        self._returned = threading.Event()  # the backend call behind the motion has returned
        self._runner: threading.Thread | None = None  # the thread running that call, once it runs
        if run is not None:
            self._start(run)

    # -- the side that runs and ends motions (the Gripper) ---------------------------------------------

    def _start(self, run: Callable[[], T], spawn: Spawn | None = None) -> None:
        """Run the backend call in a thread of its own, or through ``spawn`` (the asyncio face runs motions
        on a fixed pool of threads, so concurrent awaits never add one)."""

        def body() -> None:
            self._runner = threading.current_thread()
            try:
                self._run(run)
            finally:
                self._returned.set()

        self._submitted = True
        (spawn or _thread_of_its_own)(body, f"grippers-{self.name}")

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
                    if isinstance(error, CommandFailed) and self._abort.status is None:
                        # and its status code (a WSG's E_CMD_ABORTED), for code that checks .status
                        self._abort.status, self._abort.status_name = error.status, error.status_name
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
        """Its backend call is still to run or runs (even when the handle has been settled as superseded)."""
        return self._submitted and not self._returned.is_set()

    def _runs_in(self, thread: threading.Thread) -> bool:
        return self._runner is thread and self._busy()

    def _call(self, fn: Callable[[MotionHandle[T]], Any]) -> None:
        try:
            fn(self)
        except Exception:  # one broken callback must not keep the others (or the motion thread) from running
            log.exception("a motion handle's done callback raised")

    # -- the user's side -----------------------------------------------------------------------------

    def done(self) -> bool:
        """Whether the motion has ended (successfully or not): ``wait()`` then returns or raises at once."""
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
        return cast(T, self._result)  # set with _done, before any wait returns

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
        if self._submitted and self._runner is not threading.current_thread():
            self._returned.wait(wait_seconds(timeout, self.name, self.device))

    def __repr__(self) -> str:
        state = "done" if self.done() else "running"
        return f"<MotionHandle {self.name} {state}>"


class MotionSupervisor:
    """The rule above for one gripper: registers motions, supersedes, aborts, and stops after Ctrl-C.

    It shares the gripper's lock, so registering a motion is atomic with the gripper's closed check and
    close() sees every handle. Everything device-specific comes in as callables from the Gripper.
    """

    def __init__(
        self,
        lock: threading.Lock,
        *,
        device: Callable[[], str],
        check_open: Callable[[str], None],
        is_closed: Callable[[], bool],
        stop: Callable[[], None],
        supersede: Callable[[], None],
        settle_time: Callable[[], float],
    ) -> None:
        self._lock = lock
        self._device = device
        self._check_open = check_open
        self._is_closed = is_closed
        self._stop = stop
        self._supersede = supersede
        self._settle_time = settle_time
        self.handles: list[MotionHandle[Any]] = []
        self.spawn: Spawn | None = None  # where motions run; None: a thread each (grippers.aio sets a pool)

    def run(self, name: str, call: Callable[[], T], wait: bool, *, timeout: float, what: str = "") -> Any:
        """Start ``call`` (the backend's blocking motion) in its own thread, superseding any running motion;
        return its handle, or (``wait``) its result.

        The blocking form waits for that thread, so Ctrl-C lands in this wait and never in the middle of an
        exchange: the motion is then stopped (bounded) before the exception leaves the call.
        """
        device = self._device()
        superseded: list[MotionHandle[Any]] = []
        with self._lock:
            self._check_open(name)
            handle: MotionHandle[T] = MotionHandle(name, device=device)
            handle._cancel = lambda: self.abort("cancel()", handle)
            me = threading.current_thread()  # a done callback starting a motion must not wait for itself
            previous = [h for h in self.handles if h._busy() and h._runner is not me]
            for h in previous:
                error = CommandFailed(f"superseded by {name}{what}", device=device, command=h.name)
                if h._mark_aborted(error):
                    superseded.append(h)
            self.handles = [*previous, handle]
            stop_first = bool(superseded)  # an older motion still ran: stop it on the device first
            handle._start(lambda: self._body(handle, call, previous, stop_first), self.spawn)
        for h in superseded:  # outside the lock: done callbacks may call back into the gripper
            h._settle_aborted()
        if not wait:
            return handle
        return self._wait(handle, timeout + 2 * self._settle_time() + 1.0)

    def _body(
        self,
        handle: MotionHandle[T],
        call: Callable[[], T],
        previous: list[MotionHandle[Any]],
        stop_first: bool,
    ) -> T:
        # Stop the device, then let the older calls end (their replies, their polls) before sending: two
        # motion calls at once would share one device and muddle each other's replies.
        if stop_first:
            try:
                self._supersede()
            except Exception as exc:
                log.debug("%s: stopping the superseded motion failed: %s", self._device(), exc)
        running = [h for h in previous if h._busy()]
        if running:
            deadline = time.monotonic() + self._settle_time()
            for h in running:
                h.join(max(0.0, deadline - time.monotonic()))
        self.may_send(handle)
        return call()

    def supersede(self, by: str) -> None:
        """End the running motions for a command that is not a motion of its own (``servo()``), as
        :meth:`run` does for a newer motion: they raise "superseded by …" at once, the device is stopped,
        and their calls are given (bounded) time to return, so nothing of theirs lands after ``by`` begins.

        Without it a servo target waited for a WSG move to end (the device refuses a motion while one
        runs), an MSG move took the servo target's arrival for its own and reported success at another
        width, and an MSG home() overtaken by servo() ran on to its timeout."""
        device = self._device()
        me = threading.current_thread()
        with self._lock:
            running = [h for h in self.handles if h._busy() and h._runner is not me]
            marked = [
                h
                for h in running
                if h._mark_aborted(CommandFailed(f"superseded by {by}", device=device, command=h.name))
            ]
        for h in marked:
            h._settle_aborted()
        if not running:
            return
        try:
            self._supersede()
        except Exception as exc:  # the newer command goes on; it meets the device's state itself
            log.debug("%s: stopping the superseded motion failed: %s", device, exc)
        deadline = time.monotonic() + self._settle_time()
        for h in running:
            h.join(max(0.0, deadline - time.monotonic()))

    def may_send(self, handle: MotionHandle[Any]) -> None:
        """Raise instead of sending when the motion was ended (or the gripper closed) before it began."""
        with self._lock:
            if self._is_closed():
                raise GripperError(
                    "the gripper was closed before the motion began",
                    device=self._device(),
                    command=handle.name,
                )
            if handle._ended():  # the handle holds the reason; this error is discarded
                raise CommandFailed("ended before it was sent", device=self._device(), command=handle.name)

    def current(self) -> MotionHandle[Any] | None:
        """The motion whose thread calls this (a backend call checking it may go on), if any."""
        me = threading.current_thread()
        with self._lock:
            return next((h for h in self.handles if h._runs_in(me)), None)

    def take_all(self) -> list[MotionHandle[Any]]:
        """Forget every handle (the gripper closes); the caller holds the lock."""
        handles, self.handles = self.handles, []
        return handles

    def _wait(self, handle: MotionHandle[T], bound: float) -> T:
        try:
            return handle.wait(bound)
        except BaseException as exc:
            if handle.done():
                raise  # the motion's own outcome
            # Ctrl-C, a signal handler's exception, or the bound running out: stop the gripper first, so a
            # script that is interrupted does not leave the jaws closing on whatever is between them.
            by = stopped_by(exc)
            failure = self.abort(by, handle, bounded=True)
            if failure is not None:
                exc.add_note(f"{self._device()}: stopping the gripper after {by} failed: {failure}")
            raise

    def abort(
        self,
        by: str,
        only: MotionHandle[Any] | None = None,
        *,
        bounded: bool = False,
        device_stop: Callable[[], None] | None = None,
    ) -> BaseException | None:
        """Mark motions aborted by ``by``, stop the device, settle them; returns a bounded stop's error.

        Without ``only`` the device is stopped even when no motion runs (``stop()`` always stops)."""
        device = self._device()
        with self._lock:
            targets = [only] if only is not None else list(self.handles)
            marked = [
                h
                for h in targets
                if h._mark_aborted(CommandFailed(f"aborted by {by}", device=device, command=h.name))
            ]
        stop = device_stop or self._stop
        try:
            if only is not None and not marked:
                return None  # that motion had already ended: nothing to stop
            if bounded:
                return self._bounded(stop, by)
            stop()
            return None
        finally:
            for h in marked:
                h._settle_aborted()

    def _bounded(self, fn: Callable[[], None], why: str) -> BaseException | None:
        """Run ``fn`` in its own thread and wait a bounded time: a stop after Ctrl-C must never hang, and a
        second Ctrl-C ends the wait (the stop goes on in its thread) instead of interrupting an exchange."""
        outcome: list[BaseException | None] = []

        def run() -> None:
            try:
                fn()
                outcome.append(None)
            except BaseException as exc:
                outcome.append(exc)

        thread = threading.Thread(target=run, name=f"grippers-stop-after-{why}", daemon=True)
        thread.start()
        limit = self._settle_time()
        try:
            thread.join(limit)
        except BaseException as exc:
            return exc
        if not outcome:
            return GripperTimeout(f"no answer within {limit:g} s", device=self._device(), command="stop")
        return outcome[0]
