"""The transport-independent half of a WSG simulator server: one thread, one model, faults, timing.

Every transport (TCP, UDP, pty, CAN) differs only in how bytes come in and go out, so this base class owns
everything else: the scaled clock that advances the model, the per-link packet parsers (the client's
own :class:`~grippers.drivers.wsg.protocol.PacketParser`), the silent-gap resynchronisation, the fault hooks
applied to each outgoing packet, and the timing of due packets (async final replies, auto updates), which the
model announces with ``next_event_time`` so the thread sleeps exactly until then instead of polling.
"""

from __future__ import annotations

import heapq
import itertools
import threading
import time
from collections.abc import Callable

from ...closing import Closing
from ...simkit import FaultHooks, SimClock, apply_fault, first_half, flip_last_byte
from ..protocol import ChecksumError, Packet, PacketParser
from .model import WsgModel

# docs/protocols.md §1 (docs/protocols.md §1): on a SERIAL line a device drops a half-received packet after a
# silent gap of tens of milliseconds. Not on TCP (a request written in pieces, or paused 40 ms by a delayed
# ACK, is still one request) nor on CAN: there the size field ends a packet.
SILENT_GAP_S = 0.03
# Longest the server thread sleeps: bounds how late it notices close(), request_close() and test pokes.
MAX_WAIT_S = 0.02


class Link:
    """One conversation with the model: its connection id, its receive parser and how to send on it."""

    def __init__(
        self,
        conn: int,
        parser: PacketParser,
        send: Callable[[bytes], None],
        name: str,
        *,
        silent_gap: bool = False,
    ) -> None:
        self.conn = conn
        self.parser = parser
        self.send = send
        self.name = name
        self.silent_gap = silent_gap  # a serial line: a pause drops a half-received packet
        self.last_rx = time.monotonic()


class SimServer(Closing):
    """A running simulator: ``.url`` to connect to, ``.model``, ``.faults``, ``.clock``; ``close()`` stops it.

    Tests that poke the model directly (``server.model.…``) hold ``server.lock`` meanwhile, or use the
    helpers :meth:`remove_part` / :meth:`place_part`, which do.
    """

    url: str = ""
    close_wait_s = 5.0  # how long close() waits for the thread before leaving the release to the thread

    def __init__(self, model: WsgModel, *, time_scale: float = 1.0) -> None:
        self.model = model
        self.clock = SimClock(time_scale)
        self.faults = FaultHooks()
        self.lock = threading.RLock()
        self.error: BaseException | None = None  # what killed the server thread, if anything did
        self._links: dict[int, Link] = {}
        self._delayed: list[tuple[float, int, Link, bytes]] = []
        self._seq = itertools.count()
        self._closed = threading.Event()
        self._close_lock = threading.Lock()
        self._closing = False  # close() was called
        self._released = False  # _release() ran: by close(), or by the thread when close() gave up on it
        self._thread: threading.Thread | None = None

    # ------------------------------------------------------------------ life cycle

    def _start(self, name: str) -> None:
        self._thread = threading.Thread(target=self._run, name=name, daemon=True)
        self._thread.start()

    def close(self) -> None:
        """Stop the thread and release every socket, fd and bus; safe to call twice."""
        with self._close_lock:
            if self._closing:
                return
            self._closing = True
        self._closed.set()
        self._wake()
        thread = self._thread
        if thread is not None and thread is not threading.current_thread():
            thread.join(timeout=self.close_wait_s)
            if thread.is_alive():
                # Still running (a starved CPU): it releases everything itself as it ends (_run). Released
                # here, a descriptor number could go to the next socket or pty this process opens while the
                # old thread still reads and writes it: a new client answered by an old model.
                return
        self._release()

    def _release(self) -> None:
        """Disconnect every link and close the transport, once (by close(), or by the thread as it ends)."""
        with self._close_lock:
            if self._released:
                return
            self._released = True
        with self.lock:
            for link in list(self._links.values()):
                self.model.disconnect(link.conn)
            self._links.clear()
            self._delayed.clear()
            self._close_transport()

    @property
    def closed(self) -> bool:
        return self._closed.is_set()

    # ------------------------------------------------------------------ test helpers

    def remove_part(self) -> None:
        with self.lock:
            self.model.remove_part(self.clock.now())
        self._wake()

    def place_part(self, width_mm: float) -> None:
        with self.lock:
            self.model.place_part(width_mm, self.clock.now())
        self._wake()

    # ------------------------------------------------------------------ transport hooks

    def _wait_and_read(self, timeout: float) -> None:
        """Block up to ``timeout`` s for input and hand what arrives to :meth:`_received`."""
        raise NotImplementedError

    def _wake(self) -> None:
        """Interrupt :meth:`_wait_and_read` (no-op where the wait is short anyway)."""

    def _drop_links(self) -> None:
        """``faults.request_close()``: the server ends its connections (transports without any: no-op)."""

    def _close_transport(self) -> None:
        raise NotImplementedError

    # ------------------------------------------------------------------ the loop

    def _add_link(self, link: Link) -> None:
        self._links[link.conn] = link

    def _lost_link(self, link: Link) -> None:
        """The peer went away without 07h (TCP): WSG manual 4.0.x §1.4.2, the gripper enters FAST STOP."""
        with self.lock:
            if self._links.pop(link.conn, None) is not None:
                self.model.connection_lost(self.clock.now(), link.conn)

    def _run(self) -> None:
        try:
            while not self._closed.is_set():
                self._wait_and_read(self._timeout())
                if self._closed.is_set():
                    break
                self._service()
        except BaseException as exc:  # noqa: BLE001 - kept for tests; the thread must not die silently
            if not self._closed.is_set():
                self.error = exc
                raise
        finally:
            if self._closed.is_set():  # close() may have given up waiting for this thread: released last
                self._release()

    def _timeout(self) -> float:
        with self.lock:
            wait = MAX_WAIT_S
            due = self.model.next_event_time()
            if due is not None:
                wait = min(wait, self.clock.wall(due - self.clock.now()))
            if self._delayed:
                wait = min(wait, self._delayed[0][0] - time.monotonic())
            for link in self._links.values():
                if link.silent_gap and link.parser.buffered:
                    wait = min(wait, link.last_rx + SILENT_GAP_S - time.monotonic())
            return max(wait, 0.0)

    def _received(self, link: Link, data: bytes, *, datagram: bool = False) -> None:
        """Bytes from a peer. A datagram is a whole message: a partial packet in it is dropped at once."""
        with self.lock:
            link.last_rx = time.monotonic()
            events = link.parser.feed(data)
            while datagram and link.parser.buffered:
                link.parser.reset()
                events += link.parser.feed(b"")
            now = self.clock.now()
            for event in events:
                if isinstance(event, Packet):
                    self._emit(link, self.model.handle(event, now, link.conn))
                elif isinstance(event, ChecksumError):
                    self._emit(link, self.model.checksum_failed(event.command, now, link.conn))
                # BadLength / Discarded: noise the device ignores.

    def _service(self) -> None:
        if self.faults.close_requested.is_set():
            self.faults.close_requested.clear()
            self._drop_links()
        with self.lock:
            wall = time.monotonic()
            for link in list(self._links.values()):
                if link.silent_gap and link.parser.buffered and wall - link.last_rx >= SILENT_GAP_S:
                    link.parser.reset()
                    link.last_rx = wall
                    self._received(link, b"")
            for conn, data in self.model.advance_by_connection(self.clock.now()):
                target = self._links.get(conn)
                if target is not None:
                    self._emit(target, [data])
            while self._delayed and self._delayed[0][0] <= wall:
                _, _, link, data = heapq.heappop(self._delayed)
                if link.conn in self._links:
                    self._send(link, data)

    def _emit(self, link: Link, packets: list[bytes]) -> None:
        """Send model output through the fault hooks (simkit.FaultHooks: one fault per packet)."""
        for data in packets:
            if self.faults.silent:
                continue
            data = self.faults.take_garbage() + data
            # simkit.apply_fault: the one meaning of each fault (CORRUPT flips the checksum's high byte)
            out, delay = apply_fault(data, self.faults.take(), corrupt=flip_last_byte, truncate=first_half)
            for packet in out:
                if delay:
                    heapq.heappush(self._delayed, (time.monotonic() + delay, next(self._seq), link, packet))
                else:
                    self._send(link, packet)

    def _send(self, link: Link, data: bytes) -> None:
        try:
            link.send(data)
        except OSError:
            self._lost_link(link)
