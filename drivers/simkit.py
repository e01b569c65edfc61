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
from collections.abc import Callable
from dataclasses import dataclass
from enum import Enum
from typing import Any, TypeVar

R = TypeVar("R")


class SimClock:
    """Simulated seconds since start: wall time multiplied by ``time_scale`` (tests use 10-100).

    A test that needs the device to be in the middle of something when it acts (a motion still running when
    a newer one arrives) holds the clock still with :meth:`pause` and moves it on with :meth:`step` or
    :meth:`resume`, instead of racing the scaled clock against the scheduler on a busy machine (issue 33 §5).
    """

    def __init__(self, time_scale: float = 1.0, *, start: float = 0.0) -> None:
        if not time_scale > 0:
            raise ValueError(f"time_scale must be positive, not {time_scale!r}")
        self.time_scale = float(time_scale)
        self.start = float(start)  # simulated seconds at creation (a model prepared in simulated time)
        # (wall origin, simulated seconds when paused or None): one tuple, so now() reads it whole
        self._state: tuple[float, float | None] = (time.monotonic(), None)
        self._lock = threading.Lock()
        self._creep = 0.0

    def now(self) -> float:
        t0, held = self._state
        if held is None:
            return self.start + (time.monotonic() - t0) * self.time_scale
        if self._creep:
            with self._lock:
                t0, held = self._state
                if held is not None:
                    held += self._creep
                    self._state = (t0, held)
                    return held
            return self.now()
        return held

    def pause(self, *, creep: float = 0.0) -> None:
        """Hold simulated time where it is (the device stands still) until :meth:`resume`.

        ``creep``: simulated seconds each reading of the held clock moves it on. Frames never reach a real
        device at one instant, and a model that tells two frames apart by time needs them apart: the MSG's
        firmware takes a poll within one control tick (160-200 us) of a new command as cancelling that
        command's at-position reset, so a held MSG is read with a creep longer than a tick."""
        with self._lock:
            if self._state[1] is None:
                t0 = self._state[0]
                self._state = (t0, self.start + (time.monotonic() - t0) * self.time_scale)
            self._creep = max(0.0, float(creep))

    def step(self, simulated_seconds: float) -> None:
        """Move a paused clock on by ``simulated_seconds`` (it stays paused)."""
        with self._lock:
            t0, held = self._state
            if held is None:
                raise RuntimeError("step() needs a paused clock")
            self._state = (t0, held + simulated_seconds)

    def resume(self) -> None:
        """Let simulated time run again from where it was held."""
        with self._lock:
            held = self._state[1]
            if held is not None:
                self._state = (time.monotonic() - (held - self.start) / self.time_scale, None)
            self._creep = 0.0

    def wall(self, simulated_seconds: float) -> float:
        """Wall-clock seconds that ``simulated_seconds`` of device time take."""
        return simulated_seconds / self.time_scale


class FaultKind(Enum):
    """What a fault does to one reply, the same on every simulator and transport (see :func:`apply_fault`)."""

    DROP = "drop"  # the reply is never sent
    DELAY = "delay"  # the reply is sent ``seconds`` (wall time) later
    CORRUPT = (
        "corrupt"  # one byte of the reply is flipped (WSG: a checksum byte; CAN: a data byte; UART: text)
    )
    TRUNCATE = "truncate"  # only the first half of the reply is sent
    ERROR_BIT = "error_bit"  # STEPFOC CAN: the identifier carries the error bit; elsewhere sent unchanged
    DUPLICATE = "duplicate"  # the reply is sent twice (a network or proxy that repeats a packet)


@dataclass(frozen=True, slots=True)
class Fault:
    kind: FaultKind
    seconds: float = 0.0


def apply_fault(
    reply: R,
    fault: Fault | None,
    *,
    corrupt: Callable[[R], R],
    truncate: Callable[[R], R],
    error_bit: Callable[[R], R] | None = None,
) -> tuple[list[R], float]:
    """The one rule for what a fault does to a reply: the replies to put on the wire (in order) and the wall
    seconds to wait before sending them (0: now). Every simulator server calls this, so a fault means the
    same on the WSG and the MSG, over TCP, UDP, serial, CAN and the UART (issue 23 §3: ``duplicate_replies``
    used to duplicate on the WSG, send once on MSG over CAN and drop the reply on MSG over the UART). The
    callables supply the transport's own way to corrupt, truncate and (CAN only) set the error bit; a
    protocol without an error bit sends the reply unchanged for ERROR_BIT."""
    if fault is None:
        return [reply], 0.0
    kind = fault.kind
    if kind is FaultKind.DROP:
        return [], 0.0
    if kind is FaultKind.DELAY:
        return [reply], max(0.0, fault.seconds)
    if kind is FaultKind.CORRUPT:
        return [corrupt(reply)], 0.0
    if kind is FaultKind.TRUNCATE:
        return [truncate(reply)], 0.0
    if kind is FaultKind.DUPLICATE:
        return [reply, reply], 0.0
    if kind is FaultKind.ERROR_BIT:
        return [reply if error_bit is None else error_bit(reply)], 0.0
    raise AssertionError(kind)


def flip_last_byte(data: bytes) -> bytes:
    return data[:-1] + bytes([data[-1] ^ 0xFF]) if data else data


def first_half(data: bytes) -> bytes:
    return data[: len(data) // 2]


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


# The replay servers' timers (grippers sim --replay): the one part of a replay that waits, kept out of the
# sans-IO drivers/replay.py (issue 32: the test of the import graph checks that core does no I/O).
class Sender:
    """Sends each answer at its recorded delay (divided by the time scale), on timers that close() cancels."""

    def __init__(self, time_scale: float) -> None:
        self.time_scale = time_scale
        self._timers: list[threading.Timer] = []
        self._lock = threading.Lock()

    def schedule(self, answers: list[tuple[float, Any]], send: Callable[[Any], None]) -> None:
        for delay, answer in answers:
            timer = threading.Timer(delay / self.time_scale, _quiet(send), args=(answer,))
            timer.daemon = True
            with self._lock:
                self._timers = [t for t in self._timers if t.is_alive()]
                self._timers.append(timer)
            timer.start()

    def close(self) -> None:
        with self._lock:
            for timer in self._timers:
                timer.cancel()


def _quiet(send: Callable[[Any], None]) -> Callable[[Any], None]:
    def run(answer: Any) -> None:
        try:
            send(answer)
        except (OSError, ValueError):  # the client went away meanwhile
            pass

    return run
