"""Who reads a STEPFOC bus: a thread of its own, or an asyncio event loop while one is attached and runs.

Why two: a reply read by a thread reaches an asyncio task only through ``call_soon_threadsafe``, a wake of the
event loop that costs about as much as the asyncio face's whole margin over a blocked thread
(docs/performance.md, target 13). A bus with a file descriptor (SocketCAN, python-can's ``udp_multicast``)
can instead be read by the loop itself (``loop.add_reader``, as python-can's ``Notifier`` does when given a
loop): the reply is decoded on the thread whose task awaits it, with no hand-over at all; so can python-can's
``virtual`` bus as the library opens it (drivers/virtual_can.py, issue 43 §8). A bus without one (most vendor
interfaces, a ``virtual`` bus handed in already open) keeps its thread.

Why the thread stays while the loop reads (issue 33 §2): the bus is shared by every user in the process (other
grippers on other nodes, threaded or on other loops, monitors), and a loop may stop reading at any moment:
blocked in a long call, idle between ``run_until_complete`` calls, or ended without ``close()``. The thread
then watches: when the loop has shown no sign of life (its timer, a read) for :data:`STALL_S`, the thread
takes the bus back and reads it, so no other user waits on one user's loop. The loop, once it runs again,
notices it lost the bus, removes its reader and asks for the bus back; the thread hands it over.

Exactly one of the two reads at any moment, so no frame is read twice, out of order, or by nobody: ``_owner``
says who may read. Only the thread hands the bus to the loop or takes it back, and the loop reads (and the
thread takes the bus back) under ``_lock``, so a take-over never lands in the middle of a loop's read. Frames
that arrive during a hand-over wait in the socket's queue. Every change to the loop's own registration runs
on the loop's thread.

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
STALL_S = 0.2  # a loop that showed no sign of life this long gives the bus back to the thread
_HANDBACK_S = 1.0  # bound on waiting for a loop (on another thread) to remove its reader before a close
_PUMP_WAIT_S = 0.005  # a blocked loop's request, while the thread holds the bus: how often it looks again

THREAD, LOOP = "thread", "loop"


def bus_fileno(bus: can.BusABC) -> int | None:
    """The bus's file descriptor if an event loop can wait on it, else None."""
    try:
        fd = bus.fileno()
    except (NotImplementedError, OSError, AttributeError, ValueError):
        return None
    return fd if isinstance(fd, int) and fd >= 0 else None


def _signal_reads(bus: can.BusABC, on: bool) -> None:
    """Tell a bus whose descriptor is signalled only while someone waits on it (python-can's virtual bus as
    :mod:`grippers.drivers.virtual_can` opens it) that a loop now waits on it, or no longer does."""
    signal = getattr(bus, "signal_reads", None)
    if signal is not None:
        signal(on)


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
        self._lock = threading.RLock()  # a loop's read against the thread taking the bus back
        self._thread: threading.Thread | None = None
        self._thread_stop = threading.Event()
        self._owner = THREAD  # who may read now
        self._want = False  # the attached loop runs and asks for the bus (the thread hands it over)
        self._seen = 0.0  # the loop's last sign of life (time.monotonic())
        self._handovers = 0  # counts hand-overs: a late _loop_begin of an older one does nothing
        self._loop: asyncio.AbstractEventLoop | None = None  # attached: it reads whenever it can
        self._loop_ident = 0  # the loop's thread
        self._users = 0  # attach() calls not yet detached
        self._fd: int | None = None  # registered with the loop (loop's thread only)
        self._timer: asyncio.TimerHandle | None = None
        self._stopped = True
        self._failed = False  # a reader met a failed bus: both end (on_failure told once)

    @property
    def thread(self) -> threading.Thread | None:
        """The reader thread (it only watches while a loop reads)."""
        return self._thread

    @property
    def loop_reads(self) -> bool:
        """True while the attached loop holds the bus (it reads it when it runs)."""
        return self._owner == LOOP and self._loop is not None

    # -------------------------------------------------------------------------------------- any thread

    def start(self) -> None:
        """Begin reading (at open, after a reopen): the thread reads, and hands over to an attached loop."""
        self._stopped = self._failed = False
        self._owner = THREAD
        self._want = self._loop is not None
        self._thread_stop = stop = threading.Event()
        self._thread = threading.Thread(
            target=self._run, args=(stop,), name=f"stepfoc-can {self._name}", daemon=True
        )
        self._thread.start()

    def stop(self) -> None:
        """Stop reading (a close, or a reopen to follow), bounded: the thread is joined, the loop's reader
        removed on the loop's thread, before the caller shuts the bus down (its descriptor may be reused)."""
        self._stopped = True
        thread = self._thread
        self._thread_stop.set()
        if thread is not None and thread is not threading.current_thread():
            thread.join(timeout=2.0)
        loop = self._loop
        if loop is None or self._fd is None:
            return
        if threading.get_ident() == self._loop_ident or not loop.is_running():
            self._loop_end()  # on its thread, or while it runs nowhere (idle): nothing selects meanwhile
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

    def _read_one(self, bus: can.BusABC, timeout: float) -> bool:
        """One receive, whoever reads: the frame, if one came, to ``on_frame``; False when the bus failed
        (``on_failure`` told, once), which ends both readers."""
        try:
            msg = bus.recv(timeout=timeout)
        except Exception as exc:  # noqa: BLE001 - any failure of the bus ends the reader; waiters learn why
            first, self._failed = not self._failed, True
            if first and not self._stopped:  # a failure while stopping is the stop's (a bus shut down)
                self._on_failure(exc)
            return False
        if msg is not None:
            self._on_frame(msg)
        return True

    def reads_here(self) -> bool:
        """True on the attached loop's thread: a blocking wait there must :meth:`pump` (the loop cannot read
        while it is blocked). Called before each blocking request (one attribute test while no loop is
        attached); it also forgets a loop that was closed while attached (the thread reads again)."""
        loop = self._loop
        if loop is None:
            return False
        if loop.is_closed():
            self._forget_loop(loop)
            return False
        return not self._stopped and threading.get_ident() == self._loop_ident

    def pump(self, settled: Callable[[], bool], deadline: float) -> None:
        """Read the bus on this thread (the loop's, which is blocked in a request) until ``settled()`` or
        ``deadline``: the frames go where the loop's reader would have sent them. While the thread holds
        the bus (it has not handed over yet, or took it back), it reads for this request instead."""
        bus = self._source()
        while not settled() and not self._failed:
            left = deadline - time.monotonic()
            if left <= 0:
                return
            with self._lock:
                mine = self._owner == LOOP
                if mine:
                    self._seen = time.monotonic()  # blocked, but reading: alive
                    if not self._read_one(bus, min(left, READ_POLL_S)):
                        self._loop_end()
                        return
            if mine:
                self._on_tick()
            else:
                time.sleep(min(left, _PUMP_WAIT_S))

    def _forget_loop(self, loop: asyncio.AbstractEventLoop) -> None:
        """``loop`` was closed while attached: it reads nothing any more, and its registration went with its
        selector. The thread holds the bus from now on."""
        with self._lock:
            if self._loop is not loop:
                return
            if self._fd is not None:
                _signal_reads(self._source(), False)
            self._loop, self._fd, self._timer, self._users, self._want = None, None, None, 0, False
            self._owner = THREAD
        log.debug("%s: the event loop was closed while attached; the reader thread reads", self._name)

    # -------------------------------------------------------------------------------------- the loop's thread

    def attach(self, loop: asyncio.AbstractEventLoop) -> bool:
        """Let ``loop`` (running on this thread) read the bus while attached. False, and nothing changes,
        when the bus has no file descriptor, or another open loop reads it. Counted: each True needs a
        detach."""
        current = self._loop
        if current is not None and current.is_closed():
            self._forget_loop(current)
            current = None
        if current is not None:
            if current is not loop:
                return False
            self._users += 1
            return True
        if bus_fileno(self._source()) is None:
            return False
        self._loop, self._loop_ident, self._users = loop, threading.get_ident(), 1
        self._want = True  # the thread hands over at its next turn (within READ_POLL_S)
        return True

    def detach(self, loop: asyncio.AbstractEventLoop) -> None:
        """Undo one :meth:`attach`; the last one gives the bus back to the thread."""
        if self._loop is not loop:
            return
        self._users -= 1
        if self._users > 0:
            return
        with self._lock:  # no read of this loop's is under way (we are on its thread)
            self._loop_end()
            self._loop, self._want = None, False
            self._owner = THREAD

    def _loop_begin(self, loop: asyncio.AbstractEventLoop, handover: int) -> None:
        """The thread handed the bus to ``loop`` (hand-over number ``handover``): register its reader."""
        if self._stopped or self._failed or self._loop is not loop or self._fd is not None:
            return
        if self._owner != LOOP or handover != self._handovers:
            self._want = True  # taken back before this loop ran (it was idle or blocked): it runs now
            return
        bus = self._source()
        fd = bus_fileno(bus)
        if fd is None:
            return  # cannot happen for a bus attach() accepted; the thread takes the bus back when stale
        self._seen = time.monotonic()
        _signal_reads(bus, True)
        loop.add_reader(fd, self._readable)
        self._fd = fd
        self._timer = loop.call_later(READ_POLL_S, self._tick)

    def _loop_end(self) -> None:
        loop, fd = self._loop, self._fd
        self._fd = None
        if fd is not None:
            _signal_reads(self._source(), False)
        if self._timer is not None:
            self._timer.cancel()
            self._timer = None
        if loop is not None and fd is not None and not loop.is_closed():
            loop.remove_reader(fd)

    def _lost(self) -> None:
        """The thread took the bus back while this loop did not run: stop reading here, ask for it back."""
        self._loop_end()
        if not (self._stopped or self._failed):
            self._want = True

    def _readable(self) -> None:
        # One frame per wake, as python-can's Notifier reads: the selector is level-triggered, so a second
        # frame wakes the loop again, between other tasks (a flooded bus cannot starve them), and a wake
        # never pays for an empty read.
        with self._lock:
            if self._owner == LOOP:
                if not self._read_one(self._source(), 0):
                    self._loop_end()
                return
        self._lost()

    def _tick(self) -> None:
        self._seen = time.monotonic()
        if self._owner != LOOP:
            self._lost()
            return
        self._on_tick()
        loop = self._loop
        if self._fd is not None and loop is not None:
            self._timer = loop.call_later(READ_POLL_S, self._tick)

    # -------------------------------------------------------------------------------------- the thread

    def _run(self, stop: threading.Event) -> None:
        bus = self._source()
        while not stop.is_set() and not self._failed:
            if self._owner == LOOP:
                if not self._take_back_if_stalled():
                    stop.wait(READ_POLL_S)
                continue
            if self._want and self._hand_over():
                continue
            if not self._read_one(bus, READ_POLL_S):
                return
            self._on_tick()

    def _hand_over(self) -> bool:
        """Give the bus to the attached loop (it asked: ``_want``); False if it cannot take it any more."""
        loop = self._loop
        with self._lock:
            self._want = False
            if loop is None or self._loop is not loop:
                return False
            self._owner, self._seen = LOOP, time.monotonic()
            self._handovers += 1
            handover = self._handovers
        try:
            loop.call_soon_threadsafe(self._loop_begin, loop, handover)
        except RuntimeError:  # closed meanwhile: nobody will read there
            self._forget_loop(loop)
            return False
        return True

    def _take_back_if_stalled(self) -> bool:
        """The loop holds the bus: take it back if the loop was closed, or showed no sign of life for
        :data:`STALL_S` (blocked, or not running). True if the thread reads now."""
        loop = self._loop
        if loop is not None and loop.is_closed():
            self._forget_loop(loop)
            return True
        if time.monotonic() - self._seen <= STALL_S:
            return False
        with self._lock:  # after any read of the loop's that is under way
            if self._owner != LOOP or time.monotonic() - self._seen <= STALL_S:
                return self._owner == THREAD
            self._owner = THREAD
        log.debug("%s: the event loop did not read for %g s; the reader thread reads", self._name, STALL_S)
        return True
