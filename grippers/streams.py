"""State streams of the threaded face: a thread polls at a rate into a bounded queue that keeps the newest.

Apart from :mod:`grippers.gripper` because the remote client's stream (grippers/remote/stream.py) shares the
queue rule, and a stream needs nothing of the gripper but a function that reads one state.
"""

from __future__ import annotations

import logging
import queue
import threading
import time
from collections.abc import Callable, Iterator
from typing import Any

from grippers.drivers.closing import Closing
from grippers.drivers.numbers import finite

from .errors import GripperTimeout, LimitError
from .motions import wait_seconds
from .states import GripperState

__all__ = ["QueuedStream", "StateStream", "put_dropping_oldest"]

log = logging.getLogger(__name__)


def put_dropping_oldest(q: queue.Queue[Any], item: Any) -> int:
    """Put ``item`` into a bounded queue, dropping the oldest entries to make room; returns how many went.

    A state stream's reader that falls behind wants the newest states, never a producer that blocks."""
    dropped = 0
    while True:
        try:
            q.put_nowait(item)
            return dropped
        except queue.Full:
            try:
                q.get_nowait()
                dropped += 1
            except queue.Empty:
                pass


class QueuedStream(Closing):
    """What the polled stream here and the remote client's subscribed stream (grippers/remote/stream.py)
    share: the bounded queue that keeps the newest, ``get()`` with its default wait, iteration and ``with``.

    They differ only in what an error taken from the queue means (:meth:`_ends_stream`) and in how they stop.
    """

    def __init__(self, period: float, maxsize: int) -> None:
        self.period = period
        self._queue: queue.Queue[GripperState | BaseException] = queue.Queue(maxsize)
        self._stop = threading.Event()
        self.dropped = 0

    def _ends_stream(self, error: BaseException) -> bool:
        """Whether ``error``, read from the queue, ended the stream (``get()`` closes it before raising)."""
        return True

    def _put(self, item: GripperState | BaseException) -> None:
        self.dropped += put_dropping_oldest(self._queue, item)

    def __iter__(self) -> Iterator[GripperState]:
        return self

    def __next__(self) -> GripperState:
        return self.get()

    def get(self, timeout: float | None = None) -> GripperState:
        """The next state; GripperTimeout when none comes within ``timeout`` (default: ten periods + 2 s)."""
        if self._stop.is_set() and self._queue.empty():
            raise StopIteration
        chosen = wait_seconds(timeout, "stream")  # no overflow, no NaN (issue 13)
        wait = chosen if chosen is not None else 10 * self.period + 2.0
        try:
            item = self._queue.get(timeout=wait)
        except queue.Empty:
            raise GripperTimeout(f"no state within {wait:g} s", command="stream") from None
        if isinstance(item, BaseException):
            if self._ends_stream(item):
                self.close()
            raise item
        return item


class StateStream(QueuedStream):
    """States at ``rate_hz``: iterate over it, or pass a callback. Bounded: a slow reader drops the oldest."""

    def __init__(
        self,
        read: Callable[[], GripperState],
        rate_hz: float,
        callback: Callable[[GripperState], Any] | None = None,
        maxsize: int = 64,
        on_close: Callable[[StateStream], None] | None = None,
    ) -> None:
        rate = finite(rate_hz, "rate_hz", command="stream")
        if rate <= 0:
            raise LimitError(f"rate_hz must be a positive number, not {rate_hz!r}", command="stream")
        super().__init__(1.0 / rate, maxsize)
        self._read = read
        self._callback = callback
        self._on_close = on_close
        self._thread = threading.Thread(target=self._run, name="grippers-stream", daemon=True)
        self._thread.start()

    def _run(self) -> None:
        next_at = time.monotonic()
        while not self._stop.is_set():
            try:
                item: GripperState | BaseException = self._read()
            except BaseException as exc:
                item = exc
            if self._callback is not None and isinstance(item, GripperState):
                try:
                    self._callback(item)
                except Exception:  # a bug in the user's callback must not end the stream silently
                    log.exception("state stream callback raised; the stream goes on")
            else:
                self._put(item)
            if isinstance(item, BaseException) and not isinstance(item, GripperTimeout):
                return  # a lost connection ends the stream; the reader sees the error
            next_at += self.period
            delay = next_at - time.monotonic()
            if delay < 0:  # fell behind: do not burst to catch up
                next_at = time.monotonic()
                delay = 0
            self._stop.wait(delay)

    def _ends_stream(self, error: BaseException) -> bool:
        return not isinstance(error, GripperTimeout)  # one missed reading: the stream thread goes on

    def close(self) -> None:
        """Stop the stream (its thread, if it has one); idempotent."""
        self._stop.set()
        if threading.current_thread() is not self._thread:
            self._thread.join(timeout=5)
        if self._on_close is not None:
            self._on_close(self)
            self._on_close = None


class StreamSet:
    """The streams a gripper opened and has not seen closed: close() closes what is left.

    A device that pushes its states (``Device.state_source``: a subscription) feeds its own streams;
    otherwise a :class:`StateStream` polls ``read``, and with ``reconnect=true`` pauses over an outage and
    marks the gap (``watch.stream_reader``, grippers/reconnect.py)."""

    def __init__(self) -> None:
        self._lock = threading.Lock()
        self._streams: list[Any] = []

    def open(
        self,
        source: Any,
        read: Callable[[], GripperState],
        watch: Any,
        rate_hz: float,
        callback: Callable[[GripperState], Any] | None,
    ) -> Any:
        """A new stream, registered: from ``source`` (a ``Device.state_source``) if given, else polling
        ``read``."""
        if source is not None:
            s = source.subscribe(rate_hz, callback, self.forget)
        else:
            holder: list[StateStream] = []
            if watch is not None:
                read = watch.stream_reader(read, lambda: bool(holder) and holder[0]._stop.is_set())
            s = StateStream(read, rate_hz, callback, on_close=self.forget)
            holder.append(s)
        with self._lock:
            self._streams.append(s)
        return s

    def forget(self, s: Any) -> None:
        with self._lock:
            if s in self._streams:
                self._streams.remove(s)

    def take_all(self) -> list[Any]:
        with self._lock:
            streams, self._streams = self._streams, []
        return streams
