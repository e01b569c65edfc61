"""Pieces both simulators share: a scaled clock and the fault-injection hooks tests use.

The device models are pure (time is passed in); a server owns a :class:`SimClock` and asks the model to
advance to ``clock.now()`` before it answers. :class:`FaultHooks` is the one knob tests turn to make a
simulated device misbehave: the server asks :meth:`FaultHooks.take` what to do with each reply it is about to
send, so every transport applies faults the same way.
"""

from __future__ import annotations

import threading
import time
from collections import deque
from dataclasses import dataclass
from enum import Enum


class SimClock:
    """Simulated seconds since start: wall time multiplied by ``time_scale`` (tests use 10-100)."""

    def __init__(self, time_scale: float = 1.0, *, start: float = 0.0) -> None:
        if not time_scale > 0:
            raise ValueError(f"time_scale must be positive, not {time_scale!r}")
        self.time_scale = float(time_scale)
        self.start = float(start)  # simulated seconds at creation (a model prepared in simulated time)
        self._t0 = time.monotonic()

    def now(self) -> float:
        return self.start + (time.monotonic() - self._t0) * self.time_scale

    def wall(self, simulated_seconds: float) -> float:
        """Wall-clock seconds that ``simulated_seconds`` of device time take."""
        return simulated_seconds / self.time_scale


class FaultKind(Enum):
    DROP = "drop"  # the reply is never sent
    DELAY = "delay"  # the reply is sent ``seconds`` (wall time) later
    CORRUPT = "corrupt"  # one byte of the reply is flipped (WSG: a checksum byte; CAN: a data byte)
    TRUNCATE = "truncate"  # only the first half of the reply is sent
    ERROR_BIT = "error_bit"  # STEPFOC: the reply's identifier carries the error bit
    DUPLICATE = "duplicate"  # the reply is sent twice (a network or proxy that repeats a packet)


@dataclass(frozen=True, slots=True)
class Fault:
    kind: FaultKind
    seconds: float = 0.0


class FaultHooks:
    """Faults queued by a test and consumed by a simulator server, one per outgoing reply.

    Thread-safe: a test thread queues, the server thread takes. ``silent`` makes the device answer nothing
    until cleared; ``garbage`` is sent before the next reply; ``request_close()`` asks the server to drop the
    connection (TCP: without the client's 07h, so the WSG model enters FAST STOP).
    """

    def __init__(self) -> None:
        self._lock = threading.Lock()
        self._queue: deque[Fault] = deque()
        self._garbage = bytearray()
        self.silent = False
        self.close_requested = threading.Event()

    def _push(self, fault: Fault, count: int) -> None:
        with self._lock:
            self._queue.extend([fault] * count)

    def drop_replies(self, count: int = 1) -> None:
        self._push(Fault(FaultKind.DROP), count)

    def delay_replies(self, seconds: float, count: int = 1) -> None:
        self._push(Fault(FaultKind.DELAY, seconds), count)

    def duplicate_replies(self, count: int = 1) -> None:
        self._push(Fault(FaultKind.DUPLICATE), count)

    def corrupt_replies(self, count: int = 1) -> None:
        self._push(Fault(FaultKind.CORRUPT), count)

    def truncate_replies(self, count: int = 1) -> None:
        self._push(Fault(FaultKind.TRUNCATE), count)

    def error_bit_replies(self, count: int = 1) -> None:
        self._push(Fault(FaultKind.ERROR_BIT), count)

    def send_garbage(self, data: bytes) -> None:
        with self._lock:
            self._garbage += data

    def request_close(self) -> None:
        self.close_requested.set()

    def clear(self) -> None:
        with self._lock:
            self._queue.clear()
            self._garbage.clear()
        self.silent = False
        self.close_requested.clear()

    def take(self) -> Fault | None:
        """The fault to apply to the reply about to be sent, or None to send it as it is."""
        with self._lock:
            return self._queue.popleft() if self._queue else None

    def take_garbage(self) -> bytes:
        with self._lock:
            data = bytes(self._garbage)
            self._garbage.clear()
            return data
