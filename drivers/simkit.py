"""The simulator kit: a scaled clock, fault hooks, and pty/TCP servers around a byte-level device model.

Every simulator of the library is built the same way (docs/backend-kit.md):

- a **device model**, pure: requests in, replies out, time passed in (``now``, simulated seconds), nothing
  here; it reuses the driver's sans-IO codec;
- a :class:`SimClock`: wall time scaled by ``time_scale``, which a test holds still (:meth:`SimClock.pause`)
  and moves on (:meth:`SimClock.step`) instead of racing the clock against the scheduler;
- :class:`FaultHooks`, the one knob a test turns to make a device misbehave: drop, delay, corrupt, truncate
  or duplicate replies, send garbage, fall silent, stall for a while, close the connection. A server asks
  :meth:`FaultHooks.take` what to do with each reply it is about to send and applies it with
  :func:`apply_fault`, so a fault means the same on every simulator and transport;
- a :class:`SimServer` that serves the model on a pseudo-terminal (``pty``: what a USB-serial adapter's
  ``/dev/ttyUSB0`` is to a client) or on TCP (``tcp://HOST:PORT``; port 0 picks a free one), one
  :class:`DeviceSession` per connection, on one thread, with the clock and the hooks above.

A plugin's simulator is the model, a session that feeds its codec, and a :class:`SimServer` (the ACME R1's,
examples/acme_r1/acme_r1/sim.py, is the worked example).
"""

from __future__ import annotations

import contextlib
import functools
import os
import selectors
import socket
import threading
import time
from collections import deque
from collections.abc import Callable, Iterable
from dataclasses import dataclass
from enum import Enum
from typing import Any, Protocol, TypeVar

from .closing import Closing
from .errors import URLError
from .inet import tcp_listener

R = TypeVar("R")


class SimClock:
    """Simulated seconds since start: wall time multiplied by ``time_scale`` (tests use 10-100).

    A test that needs the device to be in the middle of something when it acts (a motion still running when
    a newer one arrives) holds the clock still with :meth:`pause` and moves it on with :meth:`step` or
    :meth:`resume`, instead of racing the scaled clock against the scheduler on a busy machine (issue 33 §5).
    """

    def __init__(self, time_scale: float = 1.0, *, start: float = 0.0, paused: bool = False) -> None:
        if not time_scale > 0:
            raise ValueError(f"time_scale must be positive, not {time_scale!r}")
        self.time_scale = float(time_scale)
        self.start = float(start)  # simulated seconds at creation (a model prepared in simulated time)
        # (wall origin, simulated seconds when paused or None): one tuple, so now() reads it whole
        self._state: tuple[float, float | None] = (time.monotonic(), None)
        self._lock = threading.Lock()
        self._creep = 0.0
        if paused:  # held from the start: a test steps it (a device given to a server already still)
            self._state = (self._state[0], self.start)

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
    until cleared; :meth:`stall` makes it answer nothing for a while (a device busy or rebooting: requests
    meanwhile are lost, later ones answered); ``garbage`` is sent before the next reply; ``request_close()``
    asks the server to drop its TCP connections (the WSG model: without the client's 07h, so it enters FAST
    STOP). A queued fault applies to the next reply sent, whichever connection it goes to.
    """

    def __init__(self) -> None:
        self._lock = threading.Lock()
        self._queue: deque[Fault] = deque()
        self._garbage = bytearray()
        self._silent = False
        self._stalled_until = 0.0  # time.monotonic() until which the device answers nothing
        self.close_requested = threading.Event()

    @property
    def silent(self) -> bool:
        """True while the device answers nothing: set by a test, or during a :meth:`stall`."""
        return self._silent or (self._stalled_until > 0.0 and time.monotonic() < self._stalled_until)

    @silent.setter
    def silent(self, value: bool) -> None:
        self._silent = bool(value)

    def stall(self, seconds: float) -> None:
        """Answer nothing for ``seconds`` (wall time) from now, then answer again by itself."""
        self._stalled_until = time.monotonic() + max(0.0, seconds)

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
        self._silent = False
        self._stalled_until = 0.0
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

    def outgoing(
        self,
        reply: bytes,
        *,
        corrupt: Callable[[bytes], bytes] = flip_last_byte,
        truncate: Callable[[bytes], bytes] = first_half,
    ) -> tuple[list[bytes], float]:
        """What a byte server puts on the wire for ``reply``: nothing while :attr:`silent`, else any garbage
        queued, then the next queued fault applied (:func:`apply_fault`); with the wall seconds to wait
        before sending (a delay). The whole rule in one call, so every byte server applies it alike."""
        if self.silent:
            return [], 0.0
        return apply_fault(self.take_garbage() + reply, self.take(), corrupt=corrupt, truncate=truncate)


class DeviceSession(Protocol):
    """One client's conversation with a simulated device: the bytes it sent at simulated time ``now`` in,
    the replies to send back out (each one reply, so a fault applies to it whole). A session keeps what
    belongs to one connection (a codec's partial frame); the device's state lives in the model it calls.
    It may also have ``closed(now)``, called when its connection drops."""

    def feed(self, data: bytes, now: float) -> Iterable[bytes]: ...


class _Peer:
    """One connection of a :class:`SimServer`: how to write to it, its session, and its name."""

    def __init__(self, write: Callable[[bytes], None], session: DeviceSession, name: str) -> None:
        self.write, self.session, self.name = write, session, name


class SimServer(Closing):
    """Serves a byte-level device model on a pty or TCP: ``.url``, ``.clock``, ``.faults``, ``.lock``,
    ``.error``; ``.path`` (pty) or ``.port`` (TCP); ``close()`` stops it.

    ``listen``: ``pty`` (or ``serial``) for a pseudo-terminal in raw mode, its URL ``FAMILY+serial://PATH``;
    ``tcp://HOST:PORT`` (or ``FAMILY+tcp://``; port 0: a free one), its URL ``FAMILY+tcp://HOST:PORT``.
    ``session()`` makes the :class:`DeviceSession` of each connection; ``advance(now)``, if given, moves the
    model on to simulated time ``now`` between requests too (a motion runs while nobody asks). ``clock`` and
    ``faults`` may be given (a clock made paused, faults queued before the first request): the server uses
    them from its first moment; otherwise it makes a :class:`SimClock` of ``time_scale`` and empty
    :class:`FaultHooks`. The model is
    only called under ``.lock`` (an RLock): a test that changes it (a part in the way) holds the lock too.
    An exception in the model ends the server's thread and is kept in ``.error`` (the ``gripper_sim``
    fixture reports it).
    """

    tick_s = 0.05  # the longest the thread sleeps between two ``advance`` calls

    def __init__(
        self,
        listen: str,
        session: Callable[[], DeviceSession],
        *,
        family: str,
        time_scale: float = 1.0,
        advance: Callable[[float], None] | None = None,
        clock: SimClock | None = None,
        faults: FaultHooks | None = None,
    ) -> None:
        self.clock = clock if clock is not None else SimClock(time_scale)
        self.faults = faults if faults is not None else FaultHooks()
        self.lock = threading.RLock()
        self.error: BaseException | None = None
        self.path: str | None = None
        self.port: int | None = None
        self._session, self._advance = session, advance
        self._selector = selectors.DefaultSelector()
        self._wake_r, self._wake_w = socket.socketpair()
        self._wake_r.setblocking(False)
        self._selector.register(self._wake_r, selectors.EVENT_READ, None)
        self._peers: dict[Any, _Peer] = {}
        self._delayed: list[tuple[float, _Peer, bytes]] = []
        self._closed = threading.Event()
        self._released = False  # _release() ran (by close(), or by the thread when close() gave up on it)
        self._listener: socket.socket | None = None
        self._master = self._slave = -1
        try:
            if listen in ("pty", "serial"):
                self._open_pty(family)
            else:
                self._open_tcp(listen, family)
        except BaseException:
            self._release()
            raise
        self._thread = threading.Thread(target=self._run, name=f"sim {self.url}", daemon=True)
        self._thread.start()

    # -- clock ---------------------------------------------------------------------------------------------

    def now(self) -> float:
        """Simulated seconds (the clock's, held while paused)."""
        return self.clock.now()

    def pause(self) -> None:
        """Hold the device still: simulated time stops until :meth:`resume` (or moves by :meth:`step`)."""
        self.clock.pause()

    def step(self, seconds: float) -> None:
        """Move a paused clock on by ``seconds`` simulated seconds, and the model with it."""
        self.clock.step(seconds)
        if self._advance is not None:
            with self.lock:
                self._advance(self.clock.now())

    def resume(self) -> None:
        self.clock.resume()

    # -- transports ----------------------------------------------------------------------------------------

    def _open_pty(self, family: str) -> None:
        import tty

        self._master, self._slave = os.openpty()
        tty.setraw(self._slave)  # binary frames: no echo, no CR/LF translation
        os.set_blocking(self._master, False)
        self.path = os.ttyname(self._slave)
        self.url = f"{family}+serial://{self.path}"
        self._peers[self._master] = _Peer(self._write_pty, self._session(), f"pty {self.path}")
        self._selector.register(self._master, selectors.EVENT_READ, self._read_pty)

    def _write_pty(self, data: bytes) -> None:
        view = memoryview(data)
        while view:
            try:
                n = os.write(self._master, view)
            except OSError:  # full (nobody reading) or closed: a UART loses bytes instead of blocking
                return
            view = view[n:]

    def _read_pty(self) -> None:
        try:
            data = os.read(self._master, 65536)
        except OSError:
            return
        if data:
            self._received(self._peers[self._master], data)

    def _open_tcp(self, listen: str, family: str) -> None:
        from .urls import format_host, parse_url

        url = parse_url(listen, bare_family=family, listen=True)
        if url.transport != "tcp":
            raise URLError(f"{listen}: a simulator listens on pty or tcp://HOST:PORT")
        host = url.host or "127.0.0.1"
        self._listener = tcp_listener(host, url.port or 0)
        self._listener.setblocking(False)
        self.port = self._listener.getsockname()[1]
        self.url = f"{family}+tcp://{format_host(host, self.port)}"
        self._selector.register(self._listener, selectors.EVENT_READ, self._accept)

    def _accept(self) -> None:
        assert self._listener is not None
        try:
            sock, peer = self._listener.accept()
        except OSError:
            return
        sock.settimeout(2.0)  # a client that stopped reading fails a send instead of blocking the device
        sock.setsockopt(socket.IPPROTO_TCP, socket.TCP_NODELAY, 1)
        self._peers[sock] = _Peer(functools.partial(_send_quietly, sock), self._session(), f"tcp {peer}")
        self._selector.register(sock, selectors.EVENT_READ, functools.partial(self._read_tcp, sock))

    def _read_tcp(self, sock: socket.socket) -> None:
        try:
            data = sock.recv(65536)
        except OSError:
            data = b""
        if not data:
            self._drop(sock)
            return
        self._received(self._peers[sock], data)

    def _drop(self, sock: socket.socket) -> None:
        peer = self._peers.pop(sock, None)
        with contextlib.suppress(KeyError, ValueError):
            self._selector.unregister(sock)
        with contextlib.suppress(OSError):
            sock.close()
        closed = getattr(peer.session, "closed", None) if peer is not None else None
        if closed is not None:
            with self.lock:
                closed(self.clock.now())

    def _sockets(self) -> list[socket.socket]:
        return [s for s in self._peers if isinstance(s, socket.socket)]

    # -- the loop ------------------------------------------------------------------------------------------

    def _received(self, peer: _Peer, data: bytes) -> None:
        with self.lock:
            replies = list(peer.session.feed(data, self.clock.now()))
        for reply in replies:
            out, delay = self.faults.outgoing(reply)
            for frame in out:
                if delay:
                    self._delayed.append((time.monotonic() + delay, peer, frame))
                else:
                    peer.write(frame)

    def _run(self) -> None:
        try:
            while not self._closed.is_set():
                wait = self.tick_s
                if self._delayed:
                    wait = max(0.0, min(wait, min(d[0] for d in self._delayed) - time.monotonic()))
                for key, _ in self._selector.select(wait):
                    if key.fileobj is self._wake_r:
                        with contextlib.suppress(OSError):
                            self._wake_r.recv(4096)
                    elif not self._closed.is_set():
                        key.data()
                now = time.monotonic()
                due = [d for d in self._delayed if d[0] <= now]
                self._delayed = [d for d in self._delayed if d[0] > now]
                for _, peer, frame in due:
                    peer.write(frame)
                if self.faults.close_requested.is_set():
                    self.faults.close_requested.clear()
                    for sock in self._sockets():
                        self._drop(sock)
                if self._advance is not None:
                    with self.lock:
                        self._advance(self.clock.now())
        except BaseException as exc:  # noqa: BLE001 - reported by close() and the gripper_sim fixture
            self.error = exc
        finally:
            if self._closed.is_set():  # close() may have given up waiting for this thread: released last
                self._release()

    def close(self) -> None:
        """Stop the thread, close every connection and the pty or listener; idempotent."""
        if self._closed.is_set():
            return
        self._closed.set()
        with contextlib.suppress(OSError):
            self._wake_w.send(b"\0")
        if self._thread is not threading.current_thread():
            self._thread.join(timeout=5.0)
            if self._thread.is_alive():
                # Still running (a starved CPU): it releases everything itself as it ends (_run). Released
                # here, a descriptor number could go to the next pty or socket this process opens while the
                # old thread still reads and writes it.
                return
        self._release()

    def _release(self) -> None:
        if self._released:
            return
        self._released = True
        for sock in self._sockets():
            self._drop(sock)
        if self._listener is not None:
            self._listener.close()
        for fd in (self._master, self._slave):
            if fd >= 0:
                with contextlib.suppress(OSError):
                    os.close(fd)
        self._master = self._slave = -1
        self._selector.close()
        self._wake_r.close()
        self._wake_w.close()


def _send_quietly(sock: socket.socket, data: bytes) -> None:
    with contextlib.suppress(OSError):  # the client went away: the next read of it drops the connection
        sock.sendall(data)


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
