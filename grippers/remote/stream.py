"""States of a served gripper as a Zenoh subscription delivers them: the same interface as
:class:`grippers.gripper.StateStream` (iterate, ``get(timeout)``, a callback, ``close()``), without polling.

Samples arrive on Zenoh's network thread; they are decoded there and queued (bounded: a slow reader drops the
oldest, counted in ``dropped``), and a callback, if given, runs on a thread of ours so a slow or failing user
callback never stalls the network. ``seq`` jumps are counted in ``missed``.
"""

from __future__ import annotations

import logging
import math
import queue
import threading
import time
from collections.abc import Callable
from typing import Any

from ..errors import GripperError
from ..states import GripperState
from ..streams import QueuedStream

log = logging.getLogger(__name__)


class SubscribedStream(QueuedStream):
    def __init__(
        self,
        decode: Callable[[bytes], tuple[int, GripperState]],
        rate_hz: float,
        callback: Callable[[GripperState], Any] | None = None,
        maxsize: int = 64,
        on_close: Callable[[SubscribedStream], None] | None = None,
    ) -> None:
        if not (math.isfinite(rate_hz) and rate_hz > 0):
            raise ValueError(f"rate_hz must be a positive number, not {rate_hz!r}")
        super().__init__(1.0 / rate_hz, maxsize)
        self._decode = decode
        self._callback = callback
        self._on_close = on_close
        self._lock = threading.Lock()
        self._last_at = -math.inf
        self._last_seq: int | None = None
        self._sub: Any = None
        self.missed = 0  # publications never seen (sequence gaps)
        self.out_of_order = 0
        self.error: BaseException | None = None  # what ended the stream (ConnectionLost), once it has
        self._thread: threading.Thread | None = None
        if callback is not None:
            self._thread = threading.Thread(target=self._deliver, name="grippers-remote-stream", daemon=True)
            self._thread.start()

    def attach(self, subscriber: Any) -> None:
        self._sub = subscriber

    def feed(self, data: bytes) -> None:
        """Called on Zenoh's thread for every publication."""
        if self._stop.is_set():
            return
        try:
            seq, state = self._decode(data)
        except GripperError as exc:
            log.warning("dropping a malformed state publication: %s", exc)
            return
        with self._lock:
            if self._last_seq is not None:
                if seq <= self._last_seq:
                    if seq < self._last_seq - 1_000_000:  # the server restarted: a new sequence
                        self._last_seq = None
                    else:
                        self.out_of_order += 1
                        return
                elif seq > self._last_seq + 1:
                    self.missed += seq - self._last_seq - 1
            self._last_seq = seq
            now = time.monotonic()
            if now - self._last_at < self.period * 0.9:
                return  # faster than asked: thinned, not queued
            self._last_at = now
        self._put(state)

    def fail(self, exc: BaseException) -> None:
        """The server withdrew the gripper or went away: the reader gets the error, then the stream ends.

        A callback stream is told too: the error is logged, kept in ``error`` and raised by ``get()``."""
        if self.error is not None or self._stop.is_set():
            return
        self.error = exc
        if self._callback is not None:
            log.warning("state stream ended: %s", exc)
        self._put(exc)

    def _deliver(self) -> None:
        while not self._stop.is_set():
            try:
                item = self._queue.get(timeout=0.1)
            except queue.Empty:
                continue
            if isinstance(item, BaseException):
                self._put(item)  # kept for get(): a callback stream's owner can still ask why it ended
                return
            try:
                assert self._callback is not None
                self._callback(item)
            except Exception:  # a bug in the user's callback must not end the stream silently
                log.exception("state stream callback raised; the stream goes on")

    def close(self) -> None:
        self._stop.set()
        sub, self._sub = self._sub, None
        if sub is not None:
            try:
                sub.undeclare()
            except Exception:
                pass
        if self._thread is not None and threading.current_thread() is not self._thread:
            self._thread.join(timeout=5)
        if self._on_close is not None:
            on_close, self._on_close = self._on_close, None
            on_close(self)
