"""Who reads a STEPFOC bus: a thread of its own, or an asyncio event loop while one is attached.

Why two: a reply read by a thread reaches an asyncio task only through ``call_soon_threadsafe``, a wake of the
event loop that costs about as much as the asyncio face's whole margin over a blocked thread
(docs/performance.md, target 13). A bus with a file descriptor (SocketCAN, python-can's ``udp_multicast``)
can instead be read by the loop itself (``loop.add_reader``, as python-can's ``Notifier`` does when given a
loop): the reply is decoded on the thread whose task awaits it, with no hand-over at all. A bus without one
(``virtual``, most vendor interfaces) keeps its thread.

Exactly one of the two reads at any moment, so no frame is read twice or by nobody: the thread hands over to
the loop as its last act (frames that arrive meanwhile wait in the socket's queue), and the loop hands back
by starting a fresh thread once its reader is removed. Every transition of the loop side runs on the loop's
thread; the thread side only ever asks the loop, with ``call_soon_threadsafe``.

While the loop reads, a blocking request made on the loop's own thread (a coroutine that calls the threaded
API, a misuse that blocks the loop anyway) would wait for a reply only that thread can read: :meth:`pump`
reads the bus inline for it instead, so it completes as it would have with a reader thread.
"""

from __future__ import annotations

import logging
import threading
import time
from collections.abc import Callable
from typing import TYPE_CHECKING

import can

if TYPE_CHECKING:
    import asyncio

log = logging.getLogger(__name__)

READ_POLL_S = 0.05  # the reader thread's longest block (close() returns promptly); the loop's timer period
_HANDBACK_S = 1.0  # bound on waiting for a loop (on another thread) to remove its reader before a close


def bus_fileno(bus: can.BusABC) -> int | None:
    """The bus's file descriptor if an event loop can wait on it, else None."""
    try:
        fd = bus.fileno()
    except (NotImplementedError, OSError, AttributeError, ValueError):
        return None
    return fd if isinstance(fd, int) and fd >= 0 else None


class BusReader:
    """Reads ``source()`` (the current python-can bus: a reopened bus is a new object) and hands every frame
    to ``on_frame``, calls ``on_tick`` at least every :data:`READ_POLL_S` (time outs are kept there), and
    ``on_failure`` once when the bus fails (the reader then stops; :meth:`start` after a reopen)."""

    def __init__(
        self,
        name: str,
        source: Callable[[], can.BusABC],
        on_frame: Callable[[can.Message], None],
        on_tick: Callable[[], None],
        on_failure: Callable[[BaseException], None],
    ) -> None:
        self._name = name
        self._source = source
        self._on_frame = on_frame
        self._on_tick = on_tick
        self._on_failure = on_failure
        self._thread: threading.Thread | None = None
        self._thread_stop = threading.Event()
        self._loop: asyncio.AbstractEventLoop | None = None  # attached: it reads whenever it can
        self._loop_ident = 0  # the loop's thread
        self._users = 0  # attach() calls not yet detached
        self._fd: int | None = None  # registered with the loop (it reads now)
        self._timer: asyncio.TimerHandle | None = None
        self._stopped = True

    @property
    def thread(self) -> threading.Thread | None:
        """The reader thread (None, or not alive, while a loop reads)."""
        return self._thread

    # -------------------------------------------------------------------------------------- any thread

    def start(self) -> None:
        """Begin reading (at open, after a reopen)."""
        self._stopped = False
        self._begin()

    def _begin(self) -> None:
        """Read on the attached loop if there is one still open, else on a fresh thread."""
        loop = self._loop
        if loop is not None:
            try:
                loop.call_soon_threadsafe(self._loop_begin, loop)
                return
            except RuntimeError:  # the loop was closed without detaching: a thread reads again
                self._loop = None
        self._start_thread()

    def _read_one(self, bus: can.BusABC, timeout: float, failed: Callable[[BaseException], None]) -> bool:
        """One receive, whoever reads: the frame, if one came, to ``on_frame``; False (``failed`` told)
        when the bus failed, which ends that reader."""
        try:
            msg = bus.recv(timeout=timeout)
        except Exception as exc:  # noqa: BLE001 - any failure of the bus ends the reader; waiters learn why
            failed(exc)
            return False
        if msg is not None:
            self._on_frame(msg)
        return True

    def stop(self) -> None:
        """Stop reading (a close, or a reopen to follow), bounded: the thread is joined, the loop's reader
        removed on the loop's thread, before the caller shuts the bus down (its descriptor may be reused)."""
        self._stopped = True
        self._stop_thread()
        loop = self._loop
        if loop is None or self._fd is None:
            return
        if threading.get_ident() == self._loop_ident:
            self._loop_end()
            return
        removed = threading.Event()

        def end() -> None:
            self._loop_end()
            removed.set()

        try:
            loop.call_soon_threadsafe(end)
        except RuntimeError:  # closed: its selector, and our registration with it, are gone
            self._fd = None
            return
        if not removed.wait(_HANDBACK_S):
            log.warning("%s: the event loop did not remove its reader within %g s", self._name, _HANDBACK_S)

    def reads_here(self) -> bool:
        """True on the loop's thread while the loop reads, or is about to: a blocking wait there must
        :meth:`pump` (the loop cannot read while it is blocked). Called before each blocking request (one
        attribute test while no loop is attached), it also notices a loop that was closed while attached,
        which reads nothing any more: a thread takes over."""
        loop = self._loop
        if loop is None:
            return False
        if loop.is_closed():
            self._loop, self._fd, self._timer, self._users = None, None, None, 0
            if not self._stopped and (self._thread is None or not self._thread.is_alive()):
                self._start_thread()
            return False
        return not self._stopped and threading.get_ident() == self._loop_ident

    def pump(self, settled: Callable[[], bool], deadline: float) -> None:
        """Read the bus on this thread (the loop's, which is blocked in a request) until ``settled()`` or
        ``deadline``: the frames go where the loop's reader would have sent them."""
        if self._fd is None:  # the thread is handing over to this blocked loop: take it over here
            thread = self._thread
            if thread is not None:
                thread.join(max(0.0, min(deadline - time.monotonic(), 4 * READ_POLL_S)))
            if self._loop is not None and (self._thread is None or not self._thread.is_alive()):
                self._loop_begin(self._loop)  # the hand-over already queued on the loop then does nothing
            if self._fd is None:  # a thread reads after all: the caller waits for it as usual
                return
        bus = self._source()
        while not settled():
            left = deadline - time.monotonic()
            if left <= 0:
                return
            if not self._read_one(bus, min(left, READ_POLL_S), self._loop_failed):
                return
            self._on_tick()

    # -------------------------------------------------------------------------------------- the loop's thread

    def attach(self, loop: asyncio.AbstractEventLoop) -> bool:
        """Let ``loop`` (running on this thread) read the bus while attached. False, and nothing changes,
        when the bus has no file descriptor, or another loop reads it. Counted: each True needs a detach."""
        if self._loop is not None:
            if self._loop is not loop:
                return False
            self._users += 1
            return True
        if bus_fileno(self._source()) is None:
            return False
        self._loop, self._loop_ident, self._users = loop, threading.get_ident(), 1
        if self._stopped:
            return True  # it begins at start()
        thread = self._thread
        if thread is not None and thread.is_alive():
            self._thread_stop.set()  # the thread hands over as its last act (_run)
        else:
            self._loop_begin(loop)
        return True

    def detach(self, loop: asyncio.AbstractEventLoop) -> None:
        """Undo one :meth:`attach`; the last one hands the bus back to a fresh thread."""
        if self._loop is not loop:
            return
        self._users -= 1
        if self._users > 0:
            return
        registered = self._fd is not None
        self._loop_end()
        self._loop = None  # a hand-over still on its way (_run, _loop_begin) now starts a thread instead
        if registered and not self._stopped:
            self._start_thread()

    def _loop_begin(self, loop: asyncio.AbstractEventLoop) -> None:
        if self._stopped or self._fd is not None:
            return
        if self._loop is not loop:  # detached while the thread was handing over: the thread is back
            self._start_thread()
            return
        fd = bus_fileno(self._source())
        if fd is None:
            self._start_thread()
            return
        loop.add_reader(fd, self._readable)
        self._fd = fd
        self._timer = loop.call_later(READ_POLL_S, self._tick)

    def _loop_end(self) -> None:
        loop, fd = self._loop, self._fd
        self._fd = None
        if self._timer is not None:
            self._timer.cancel()
            self._timer = None
        if loop is not None and fd is not None and not loop.is_closed():
            loop.remove_reader(fd)

    def _readable(self) -> None:
        # One frame per wake, as python-can's Notifier reads: the selector is level-triggered, so a second
        # frame wakes the loop again, between other tasks (a flooded bus cannot starve them), and a wake
        # never pays for an empty read.
        self._read_one(self._source(), 0, self._loop_failed)

    def _tick(self) -> None:
        self._on_tick()
        loop = self._loop
        if self._fd is not None and loop is not None:
            self._timer = loop.call_later(READ_POLL_S, self._tick)

    def _loop_failed(self, exc: BaseException) -> None:
        self._loop_end()
        if not self._stopped:
            self._on_failure(exc)

    # -------------------------------------------------------------------------------------- the thread

    def _start_thread(self) -> None:
        self._thread_stop = stop = threading.Event()
        self._thread = threading.Thread(
            target=self._run, args=(stop,), name=f"stepfoc-can {self._name}", daemon=True
        )
        self._thread.start()

    def _stop_thread(self) -> None:
        thread = self._thread
        self._thread_stop.set()
        if thread is not None and thread is not threading.current_thread():
            thread.join(timeout=2.0)

    def _run(self, stop: threading.Event) -> None:
        bus = self._source()

        def failed(exc: BaseException) -> None:
            if not stop.is_set():  # a failure while stopping is the stop's (a bus shut down)
                self._on_failure(exc)

        while not stop.is_set():
            if not self._read_one(bus, READ_POLL_S, failed):
                return
            self._on_tick()
        if not self._stopped:  # stopped for an attached loop: hand over (or read on, if it went meanwhile)
            self._begin()
