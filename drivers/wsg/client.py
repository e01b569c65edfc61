"""The threaded WSG client: one connection over any transport, read by whichever thread needs the bytes.

The matching rules live in :mod:`grippers.drivers.wsg.session` (sans-IO); this module adds the reading, the
waiting with timeouts, the typed command methods and the auto-update subscriptions. Any number of threads may
call the client at once: requests with different command ids run concurrently (state queries while a motion is
pending), requests with the same id take turns (see the session's docstring for why).

Who reads (leader/follower): at most one thread is inside ``transport.recv`` at a time. A caller waiting for
its reply reads the line itself when nobody else does, so a plain request costs no thread hand-over (the
round-trip benchmark, docs/performance.md); other waiters are woken when their reply goes by. A background
thread reads only when nobody waits but bytes may still come: subscriptions (their callbacks always run on
it), a pending motion's final reply, a half-received packet, or a late reply to swallow.

Ctrl-C (issue 13 item 1): a KeyboardInterrupt can arrive between any two steps of an exchange, also right
after bytes were read or while the lock is being taken back. Every step therefore leaves a trace the handler
can finish from: the reading role records its owner, bytes read wait in ``_held_read`` until matched, and the
call sites (``_exchange``, ``_motion``) rescue the exchange: what was read is matched, the role is handed
back and the exchange is abandoned as on a timeout (its late reply is swallowed, its id freed). A STOP can
then go out at once from the handler.
"""

from __future__ import annotations

import logging
import math
import threading
import time
from collections import deque
from collections.abc import Callable, Iterator
from threading import get_ident
from typing import Any, NoReturn
from urllib.parse import parse_qs, urlsplit

from can import BusABC

from ..errors import (
    CommandFailed,
    ConnectionLost,
    GripperError,
    GripperTimeout,
    LimitError,
    NotSupported,
    ProtocolError,
)
from .commands import (
    AUTO_UPDATE_COMMANDS,
    COMMANDS,
    Cmd,
    FingerFlags,
    FingerInfo,
    FirmwareVersion,
    GraspingState,
    GraspingStatistics,
    Reply,
    SoftLimits,
    SystemFlags,
    SystemInfo,
    SystemLimits,
    command_name,
    decode_reply,
    encode_request,
    reply_value,
)
from .dissect import wire_tap
from .protocol import BadLength, ChecksumError, Discarded, Packet, Status
from .session import (
    AutoUpdate,
    Completed,
    Exchange,
    ExchangeState,
    Session,
    StaleReply,
    Unsolicited,
)
from .transports import (
    DEFAULT_BAUDRATE,
    DEFAULT_CAN_RECV_ID,
    DEFAULT_CAN_SEND_ID,
    DEFAULT_TCP_PORT,
    DEFAULT_UDP_LOCAL_PORT,
    DEFAULT_UDP_PORT,
    CanTransport,
    SerialTransport,
    TcpTransport,
    Transport,
    UdpTransport,
)

__all__ = ["Pending", "Subscription", "WsgClient"]

log = logging.getLogger(__name__)

_POLL = 0.05  # the reader's receive timeout: bounds how long close() waits for the reader to notice
# docs/protocols.md §1: a half-received packet is dropped after a silent gap of tens of milliseconds.
_SILENT_GAP = 0.05
_MIN_PERIOD_MS = 10  # docs/protocols.md §1: auto-update period minimum
_MAX_TAG = 64  # WSG manual 4.0.x §3.5.2
_MAX_LOOP = 256  # WSG manual 4.0.x §3.1.1


def _finite(name: str, value: float, command: str, device: str) -> float:
    try:
        value = float(value)
    except (TypeError, ValueError):
        raise LimitError(f"{name} must be a number, not {value!r}", device=device, command=command) from None
    if not math.isfinite(value):
        raise LimitError(f"{name} must be finite, not {value!r}", device=device, command=command)
    return value


def _never(_timeout: float) -> bool:
    return False


def _always(_timeout: float) -> bool:
    return True


# The payload of a plain state query (auto update off), encoded once.
_PLAIN_QUERY: dict[int, bytes] = {cmd: encode_request(cmd) for cmd in AUTO_UPDATE_COMMANDS}


class Pending:
    """A motion command that was accepted (E_CMD_PENDING) and whose final reply is still to come."""

    def __init__(self, client: WsgClient, exchange: Exchange) -> None:
        self._client = client
        self._exchange = exchange
        self.command = exchange.command

    def done(self) -> bool:
        with self._client._cond:
            return self._exchange.finished

    def result(self, timeout: float | None = None) -> None:
        """Wait for the final reply; CommandFailed if it is not E_SUCCESS.

        ``timeout`` defaults to the client's ``motion_timeout``. A timeout here does not abandon the motion:
        ``result`` may be called again; the command id stays busy until the final reply arrives.
        """
        client = self._client
        wait = client.motion_timeout if timeout is None else timeout
        packet = client._wait(self._exchange, time.monotonic() + wait, final=True, abandon=False, waited=wait)
        client._check(self.command, packet)

    def cancel(self, timeout: float | None = None) -> None:
        """Send STOP (22h); the final reply then reports E_CMD_ABORTED through :meth:`result`.

        If no final reply comes within ``timeout`` (the client's by default) it was lost, e.g. the motion had
        ended and its reply was dropped: the exchange is then abandoned like a timed-out blocking motion, so
        its command id is free again after ``stale_final_ttl`` instead of staying busy for good.
        """
        client = self._client
        client.stop(timeout=timeout)
        wait = client.timeout if timeout is None else timeout
        try:
            client._wait(self._exchange, time.monotonic() + wait, final=True, waited=wait)
        except GripperError:
            pass  # the outcome (aborted, failed, timed out) is what result() reports

    def __repr__(self) -> str:
        return f"<Pending {command_name(self.command)} {self._exchange.state.value}>"


class Subscription:
    """Auto updates of one state command, as callbacks and as an iterator of decoded values.

    Values go to a bounded queue (``maxsize``); when it is full the OLDEST value is dropped (a consumer that
    falls behind wants the newest state) and ``dropped`` counts the losses (with a callback too: values are
    queued for the iterator either way, so a callback-only user can ignore it). Callbacks run on the client's
    reader thread: keep them short, and do not call the client from them (that would wait for the very
    thread that delivers the reply; the client refuses it with GripperError).
    """

    def __init__(
        self,
        client: WsgClient,
        command: int,
        period_ms: int,
        changes_only: bool,
        callback: Callable[[Any], None] | None,
        maxsize: int,
        timeout: float | None,
    ) -> None:
        self._client = client
        self.command = command
        self.period_ms = period_ms
        self.changes_only = changes_only
        self.timeout = timeout
        self._callback = callback
        self._queue: deque[Any] = deque(maxlen=maxsize)
        self._cv = threading.Condition()
        self._closed = False
        self._error: GripperError | None = None
        self.dropped = 0
        self.received = 0

    @property
    def closed(self) -> bool:
        return self._closed

    def _deliver(self, value: Any) -> None:
        with self._cv:
            if self._closed:
                return
            if len(self._queue) == self._queue.maxlen:
                self.dropped += 1
            self._queue.append(value)
            self.received += 1
            self._cv.notify_all()
        if self._callback is not None:
            try:
                self._callback(value)
            except Exception:
                log.exception("subscription callback for %s raised", command_name(self.command))

    def _end(self, error: GripperError | None = None) -> None:
        with self._cv:
            self._closed = True
            if error is not None and self._error is None:
                self._error = error
            self._cv.notify_all()

    def get(self, timeout: float | None = None) -> Any:
        """The next value; GripperTimeout after ``timeout`` (default: the subscription's).

        ConnectionLost when the line is gone.

        Raises GripperError once the subscription is closed and its queue is empty.
        """
        wait = self.timeout if timeout is None else timeout
        deadline = None if wait is None else time.monotonic() + wait
        with self._cv:
            while not self._queue:
                if self._error is not None:
                    raise ConnectionLost(
                        self._error.message, device=self._error.device, command=command_name(self.command)
                    )
                if self._closed:
                    raise GripperError("subscription closed", command=command_name(self.command))
                remaining = None if deadline is None else deadline - time.monotonic()
                if remaining is not None and remaining <= 0:
                    raise GripperTimeout(
                        f"no update within {wait:g} s",
                        device=self._client.device,
                        command=command_name(self.command),
                    )
                self._cv.wait(_POLL if remaining is None else min(remaining, _POLL))
            return self._queue.popleft()

    def __iter__(self) -> Iterator[Any]:
        return self

    def __next__(self) -> Any:
        with self._cv:
            if self._closed and not self._queue and self._error is None:
                raise StopIteration
        try:
            return self.get()
        except ConnectionLost:
            raise
        except GripperTimeout:
            raise
        except GripperError:
            raise StopIteration from None

    def close(self, timeout: float | None = None) -> None:
        """Stop receiving; the last subscription of a command switches the device's auto update off."""
        if self._closed:
            return
        self._end()
        self._client._unsubscribe(self, timeout)

    def __enter__(self) -> Subscription:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()


def _take_lock(lock: Any) -> BaseException | None:
    """Take ``lock`` whatever happens and return the first interrupt that landed meanwhile (None if none).

    A Ctrl-C (any BaseException) may interrupt the wait for the lock, or land just after it was taken; either
    way the caller needs the lock to put its state back before it re-raises the interrupt."""
    interrupt: BaseException | None = None
    while True:
        try:
            lock.acquire()
            return interrupt
        except BaseException as exc:  # noqa: BLE001 - handed back to the caller, which re-raises it
            interrupt = interrupt or exc
            if lock._is_owned():  # interrupted after it was taken
                return interrupt


class WsgClient:
    """A WSG gripper over one transport. Units are the device's: mm, mm/s, mm/s², N, °C.

    Every method takes ``timeout`` (seconds; default ``timeout`` for state and settings, ``motion_timeout``
    for motions). A device status other than E_SUCCESS raises CommandFailed; a lost line raises
    ConnectionLost for every waiter at once.
    """

    def __init__(
        self,
        transport: Transport,
        *,
        device: str | None = None,
        timeout: float = 1.0,
        motion_timeout: float = 60.0,
        verify_checksum: bool = True,
        stale_ttl: float = 2.0,
        stale_final_ttl: float = 60.0,
        silent_gap: float = _SILENT_GAP,
    ) -> None:
        self._transport = transport
        self.device = device or f"wsg {transport.name}"
        self._transport = wire_tap(transport, self.device)  # DEBUG on grippers.wire: every packet, decoded
        self.timeout = timeout
        self.motion_timeout = motion_timeout
        self.firmware: FirmwareVersion | None = None
        self.limits: SystemLimits | None = None
        self.stats: dict[str, int] = dict.fromkeys(
            (
                "checksum_errors",
                "bad_lengths",
                "discarded_bytes",
                "stale_replies",
                "unsolicited",
                "updates",
                "lost_replies",
                "barriers",
            ),
            0,
        )
        self._session = Session(
            verify_checksum=verify_checksum, stale_ttl=stale_ttl, stale_final_ttl=stale_final_ttl
        )
        self._silent_gap = silent_gap
        # docs/protocols.md §1 / docs/protocols.md §1: only a serial line ends a packet by a pause. A TCP
        # stream may pause 40 ms inside a reply (delayed ACK) and CAN frames may be spaced: there the size
        # field and the parser's per-id bound end a packet, never a gap.
        self._gap_rule = bool(getattr(transport, "silent_gap", False))
        self._drain = getattr(transport, "recv_nowait", None)
        # Whether anything may have arrived: a poll() bound method where the transport has one, so the drain
        # before each request costs one call into C when nothing did, which is nearly always
        # (docs/performance.md, target 2); without recv_nowait there is nothing to drain with.
        ready = getattr(transport, "ready", None)
        if self._drain is None:
            ready = _never
        self._ready: Callable[[int], Any] = ready if ready is not None else _always
        lock = threading.RLock()
        self._lock = lock  # the hot path enters the lock directly (Condition.__enter__ is Python code)
        self._cond = threading.Condition(lock)  # callers wait here for their replies
        self._sleepers = 0  # threads inside self._cond.wait: a reply with nobody asleep notifies nobody
        # The background reader waits on its own condition (same lock), so the notifications that wake
        # callers on every reply do not also wake it: a thread wake-up per exchange is what the
        # leader/follower reading is there to avoid.
        self._bg = threading.Condition(lock)
        self._subs: dict[int, list[Subscription]] = {}
        self._sub_params: dict[int, tuple[int, bool]] = {}
        self._lost: ConnectionLost | None = None
        self._closing = False
        self._closed = False
        self._stop = threading.Event()
        # One thread at a time is inside transport.recv: 0/False for nobody, else the holder (a caller's
        # thread id, or True for the reader thread).
        self._reading: int | bool = False
        # Bytes (or a failure) a caller read but has not matched yet: matched by whoever handles its Ctrl-C.
        self._held_read: tuple[bytes | None, BaseException | None] | None = None
        self._callers = 0  # callers between sending a request and leaving _wait: they read for themselves
        self._last_rx = time.monotonic()
        # Updates a caller happened to read, handed to the reader thread that runs subscription callbacks.
        self._deferred: list[tuple[Subscription, Any]] = []
        self._reader = threading.Thread(target=self._read_loop, name=f"{self.device} reader", daemon=True)
        self._reader.start()
        self._reader_ident = self._reader.ident

    # ------------------------------------------------------------------------------------------ factories

    @classmethod
    def tcp(
        cls, host: str, port: int = DEFAULT_TCP_PORT, *, connect_timeout: float | None = None, **kw: Any
    ) -> WsgClient:
        wait = connect_timeout if connect_timeout is not None else kw.get("timeout", 5.0)
        return cls(TcpTransport(host, port, connect_timeout=wait), **kw)

    @classmethod
    def udp(
        cls, host: str, port: int = DEFAULT_UDP_PORT, *, local_port: int = DEFAULT_UDP_LOCAL_PORT, **kw: Any
    ) -> WsgClient:
        return cls(UdpTransport(host, port, local_port=local_port), **kw)

    @classmethod
    def serial(
        cls,
        port: str,
        *,
        baudrate: int = DEFAULT_BAUDRATE,
        bytesize: int = 8,
        parity: str = "N",
        stopbits: float = 1,
        **kw: Any,
    ) -> WsgClient:
        return cls(
            SerialTransport(port, baudrate=baudrate, bytesize=bytesize, parity=parity, stopbits=stopbits),
            **kw,
        )

    @classmethod
    def can(
        cls,
        *,
        bus: BusABC | None = None,
        interface: str | None = None,
        channel: str | int | None = None,
        bitrate: int | None = None,
        send_id: int = DEFAULT_CAN_SEND_ID,
        recv_id: int = DEFAULT_CAN_RECV_ID,
        extended_id: bool | None = None,
        **kw: Any,
    ) -> WsgClient:
        transport = CanTransport(
            bus,
            interface=interface,
            channel=channel,
            bitrate=bitrate,
            send_id=send_id,
            recv_id=recv_id,
            extended_id=extended_id,
        )
        return cls(transport, **kw)

    @classmethod
    def from_url(cls, url: str, **kw: Any) -> WsgClient:
        """``[wsg+]tcp://H:P``, ``[wsg+]udp://H:P?local_port=N``, ``[wsg+]serial://PATH-OR-PYSERIAL-URL?baudrate=..``,
        ``[wsg+]can://INTERFACE/CHANNEL?send_id=..&recv_id=..&bitrate=..`` (the simulator's ``.url``)."""
        parts = urlsplit(url)
        scheme = parts.scheme.lower().removeprefix("wsg+")
        query = {k: v[-1] for k, v in parse_qs(parts.query).items()}

        def num(key: str, default: int | None) -> int | None:
            return int(query[key], 0) if key in query else default

        if scheme == "tcp":
            return cls.tcp(parts.hostname or "127.0.0.1", parts.port or DEFAULT_TCP_PORT, **kw)
        if scheme == "udp":
            return cls.udp(
                parts.hostname or "127.0.0.1",
                parts.port or DEFAULT_UDP_PORT,
                local_port=num("local_port", DEFAULT_UDP_LOCAL_PORT) or 0,
                **kw,
            )
        if scheme == "serial":
            rest = url.split("://", 1)[1].split("?", 1)[0]
            framing: dict[str, Any] = {"baudrate": num("baudrate", DEFAULT_BAUDRATE)}
            if "parity" in query:
                framing["parity"] = query["parity"]
            if "stopbits" in query:
                framing["stopbits"] = float(query["stopbits"])
            if "bytesize" in query:
                framing["bytesize"] = int(query["bytesize"])
            return cls.serial(rest, **framing, **kw)
        if scheme == "can":
            return cls.can(
                interface=parts.netloc or None,
                channel=parts.path.lstrip("/") or None,
                bitrate=num("bitrate", None),
                send_id=num("send_id", DEFAULT_CAN_SEND_ID) or 0,
                recv_id=num("recv_id", DEFAULT_CAN_RECV_ID) or 0,
                extended_id=(
                    query["extended"].lower() in ("1", "true", "yes") if "extended" in query else None
                ),
                **kw,
            )
        raise LimitError(f"unsupported WSG URL {url!r} (tcp, udp, serial or can)")

    # -------------------------------------------------------------------------------------------- lifetime

    def close(self, timeout: float | None = None) -> None:
        """Switch auto updates off, announce the disconnect (TCP: 07h, so no FAST STOP), stop the reader.

        Idempotent; never raises for a line that is already gone.
        """
        with self._cond:
            if self._closing or self._closed:
                return
            self._closing = True
            healthy = self._lost is None
        goodbye = min(self.timeout, 0.5) if timeout is None else timeout
        if healthy and threading.current_thread() is not self._reader:
            for cmd in list(self._sub_params):
                try:
                    self._call(cmd, payload=encode_request(cmd), timeout=goodbye, internal=True)
                except GripperError:
                    pass
            if self._transport.connection_oriented:
                try:
                    self._call(Cmd.DISCONNECT, timeout=goodbye, internal=True)
                except GripperError:
                    pass
        self._stop.set()
        with self._cond:
            self._bg.notify()
        if threading.current_thread() is not self._reader:
            self._reader.join(timeout=2.0)
        try:
            self._transport.close()
        except Exception:  # noqa: BLE001 - closing must not fail
            log.debug("closing %s failed", self.device, exc_info=True)
        error = ConnectionLost("client closed", device=self.device)
        with self._cond:
            self._closed = True
            self._session.fail_all(error)
            subs = [s for lst in self._subs.values() for s in lst]
            self._subs.clear()
            self._sub_params.clear()
            self._cond.notify_all()
        for sub in subs:
            sub._end()

    @property
    def closed(self) -> bool:
        return self._closed

    @property
    def connection_lost(self) -> ConnectionLost | None:
        return self._lost

    def __enter__(self) -> WsgClient:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()

    def __repr__(self) -> str:
        return f"<WsgClient {self.device}{' closed' if self._closed else ''}>"

    # ------------------------------------------------------------------------------------------- reader

    def _background_needed(self) -> bool:
        """Whether bytes may arrive that no waiting caller will read (called with ``_cond`` held)."""
        if self._subs or self._deferred or self._session.parser.buffered:
            return True
        return not self._callers and self._session.expecting(time.monotonic())

    def _read_loop(self) -> None:
        while True:
            with self._lock:
                while not self._stop.is_set() and (self._reading or not self._background_needed()):
                    self._bg.wait(_POLL)
                if self._stop.is_set():
                    return
                self._reading = True
                deliveries, self._deferred = self._deferred, []
            for sub, value in deliveries:
                sub._deliver(value)
            data = self._receive(_POLL)
            if data is None:
                return
            with self._lock:
                found = self._process(data)
            for sub, value in found:
                sub._deliver(value)

    def _receive(self, timeout: float) -> bytes | None:
        """One ``transport.recv`` by the thread holding the reading role, called WITHOUT the lock.

        None when the line is gone: the role is then released and every waiter failed with ConnectionLost.
        On success the role stays taken until :meth:`_process` hands it back under the lock, so no second
        reader can slip in between the bytes and their matching.
        """
        try:
            return self._transport.recv(timeout)
        except BaseException as exc:  # a transport bug must still release every waiter
            with self._lock:
                self._reading = False
                self._cond.notify_all()
            if not isinstance(exc, Exception):  # KeyboardInterrupt: only this reader is gone
                raise
            if not self._stop.is_set():
                lost = (
                    exc
                    if isinstance(exc, ConnectionLost)
                    else ConnectionLost(f"reader failed: {exc!r}", device=self.device)
                )
                self._connection_lost(lost)
            return None

    def _process(self, data: bytes) -> list[tuple[Subscription, Any]]:
        """Match received bytes and hand the reading role back (called with the lock held).

        Returns the subscription values found; the caller decides on which thread they are delivered.
        """
        self._reading = False
        now = time.monotonic()
        try:
            session = self._session
            if data:
                self._last_rx = now
                events = session.receive(data, now)
            elif self._gap_rule and session.parser.buffered and now - self._last_rx >= self._silent_gap:
                events = session.reset_parser(now)
            else:
                events = []
            return self._dispatch(events) if events else []
        except Exception:  # noqa: BLE001 - garbage on the line never kills the reading
            log.exception("%s: reader ignored an unexpected error", self.device)
            return []
        finally:
            if self._sleepers:
                self._cond.notify_all()  # replies may have arrived, and the reading role is free

    def _dispatch(self, events: list[Any]) -> list[tuple[Subscription, Any]]:
        deliveries: list[tuple[Subscription, Any]] = []
        stats = self.stats
        for ev in events:
            if type(ev) is Completed:  # the common case: the waiter picks its reply from the exchange
                continue
            if isinstance(ev, AutoUpdate):
                stats["updates"] += 1
                subs = self._subs.get(ev.packet.command)
                if not subs:
                    continue
                try:
                    reply = decode_reply(ev.packet.command, ev.packet.payload)
                except ProtocolError:
                    log.debug("%s: undecodable update %r", self.device, ev.packet)
                    continue
                if reply.ok:
                    deliveries.extend((sub, reply.value) for sub in subs)
            elif isinstance(ev, StaleReply):
                stats["stale_replies"] += 1
                log.debug("%s: late reply swallowed: %r", self.device, ev.packet)
            elif isinstance(ev, Unsolicited):
                stats["unsolicited"] += 1
                log.debug("%s: unsolicited packet: %r", self.device, ev.packet)
            elif isinstance(ev, ChecksumError):
                stats["checksum_errors"] += 1
            elif isinstance(ev, BadLength):
                stats["bad_lengths"] += 1
            elif isinstance(ev, Discarded):
                stats["discarded_bytes"] += len(ev.raw)
        return deliveries

    def _connection_lost(self, error: ConnectionLost) -> None:
        with self._cond:
            if self._lost is None:
                self._lost = error
            self._session.fail_all(error)
            subs = [s for lst in self._subs.values() for s in lst]
            self._cond.notify_all()
        for sub in subs:
            sub._end(error)

    # -------------------------------------------------------------------------------------- exchanges

    def _usable(self, name: str, internal: bool) -> None:
        if self._lost is not None:
            raise ConnectionLost(self._lost.message, device=self.device, command=name)
        if self._closed or (self._closing and not internal):
            raise ConnectionLost("client is closed", device=self.device, command=name)

    def _check_supported(self, cmd: int) -> None:
        s = COMMANDS.get(cmd)
        fw = self.firmware
        if s is not None and fw is not None and fw.major < s.min_firmware_major:
            raise NotSupported(
                f"not available in firmware {fw} (the 2.x command set has no 46h or finger commands)",
                device=self.device,
                command=command_name(cmd),
            )

    def _encode(self, cmd: int, **fields: Any) -> bytes:
        try:
            return encode_request(cmd, **fields)
        except (LimitError, ProtocolError) as exc:
            raise type(exc)(exc.message, device=self.device, command=command_name(cmd)) from None

    def _begin(
        self, cmd: int, payload: bytes, deadline: float, *, internal: bool = False
    ) -> tuple[Exchange, bool]:
        """Register and send a request; the caller is counted in ``_callers`` until its ``_wait(begun=True)``.

        Also returns whether the caller took the reading role here (``lead``): when nobody else reads and no
        subscription needs the reader thread, taking it in the same critical section as the send saves the
        lock round trip before the read, which is a good part of a round trip's cost (docs/performance.md).
        """
        me = get_ident()
        if me == self._reader_ident:
            raise GripperError(
                "commands cannot be issued from a subscription callback (reader thread)",
                device=self.device,
                command=command_name(cmd),
            )
        session = self._session
        exchange: Exchange | None = None
        lead = False
        try:
            with self._lock:
                while True:
                    if self._lost is not None or self._closing or self._closed:
                        self._usable(command_name(cmd), internal)
                    if not self._reading and not self._subs and self._ready(0):
                        self._drain_line()
                    now = time.monotonic()
                    before = session.seq
                    try:
                        opened = session.open(cmd, payload, now)
                    except BaseException:  # Ctrl-C right after open(): its result is lost, not the slot
                        session.withdraw(cmd, before)
                        raise
                    if opened is not None:
                        exchange, raw = opened
                        self._callers += 1  # released by the _wait(begun=True) that follows
                        lead = not (self._reading or self._subs or self._closing)
                        if lead:
                            self._reading = me  # the role's owner: a rescue after Ctrl-C hands it back
                        break
                    self._wait_for_slot(cmd, now, deadline, internal)
            self._transport.send(raw)
        except BaseException as exc:
            if exchange is None:
                raise
            with self._lock:
                self._callers -= 1
                if lead:  # never leave the reading role taken by a caller that is gone
                    self._reading = False
                    self._cond.notify_all()
                if not isinstance(exc, ConnectionLost):
                    # Interrupted (KeyboardInterrupt) or refused: whether the bytes left is unknown, so the
                    # slot is held like a timed-out request's, long enough to swallow a late reply.
                    session.abandon(exchange, time.monotonic())
            if not isinstance(exc, ConnectionLost):
                raise
            self._connection_lost(exc)  # fails the exchange and wakes everybody
            raise ConnectionLost(exc.message, device=self.device, command=command_name(cmd)) from None
        return exchange, lead

    def _sleep(self, timeout: float) -> None:
        """Wait on ``_cond`` (lock held), counted so that a reply with nobody asleep skips the notify."""
        self._sleepers += 1
        try:
            self._cond.wait(timeout)
        finally:
            self._sleepers -= 1

    def _wait_for_slot(self, cmd: int, now: float, deadline: float, internal: bool) -> None:
        """The slot of ``cmd`` is held (lock held): wait a little, or run the barrier that proves a stale
        reply lost (with the lock released); GripperTimeout at the deadline."""
        if deadline - now <= 0:
            raise GripperTimeout(
                "a previous exchange of this command is still outstanding (one per command id)",
                device=self.device,
                command=command_name(cmd),
            )
        session = self._session
        if not session.needs_barrier(cmd, now):
            self._sleep(min(deadline - now, _POLL))
            return
        self._lock.release()  # _begin holds it once (its own ``with``)
        try:
            self._barrier(cmd, deadline, internal)
        finally:
            interrupt = self._relock()
        session.is_busy(cmd, time.monotonic())  # drops the marker the barrier proved lost
        self.stats["lost_replies"] = session.lost_replies
        if interrupt is not None:
            raise interrupt

    def _drain_line(self) -> None:
        """Match what already arrived before a new request is registered (lock held, nobody reading).

        Why: a packet nobody waits for (a duplicated reply, a reply whose marker a proof removed) must be
        consumed and counted now; read after the new request went out it would look like that request's
        reply. One non-blocking read: the line is idle, so it nearly always returns nothing.
        """
        try:
            data = self._drain()  # type: ignore[misc] - _ready is _never without it
        except ConnectionLost:
            return  # the next read reports it to everybody
        if data:
            self._absorb(data)  # nobody reads (checked by the caller) and the lock is held

    def _barrier(self, cmd: int, deadline: float, internal: bool) -> None:
        """Prove a stale reply of ``cmd`` lost: a LOOP with a fresh nonce, answered after anything sent
        before it (the device answers in order). GripperTimeout when even that gets no reply."""
        self.stats["barriers"] += 1
        nonce = self._session.barrier_payload()
        wait = max(deadline - time.monotonic(), 0.001)
        try:
            packet = self._exchange(Cmd.LOOP, nonce, wait, internal)
        except GripperTimeout:
            raise GripperTimeout(
                "a previous exchange of this command is still outstanding (one per command id) and the "
                "device did not answer the LOOP that would prove its reply lost",
                device=self.device,
                command=command_name(cmd),
            ) from None
        if packet.status:
            log.debug("%s: barrier LOOP answered %s", self.device, Status.describe(packet.status))

    def _relock(self) -> BaseException | None:
        """Take the lock after a read even if Ctrl-C interrupts the wait for it; returns the interrupt.

        Why: bytes just read must be matched, and the reading role handed back, whatever happens; an
        interrupted acquire would lose both (and every later caller would wait for a reader that is gone).
        """
        interrupt: BaseException | None = None
        while True:
            try:
                self._lock.acquire()
                return interrupt
            except BaseException as exc:  # noqa: BLE001 - KeyboardInterrupt: re-raised by the caller
                interrupt = interrupt or exc

    def _read_own_reply(self, exchange: Exchange, wait: float) -> Packet | None:
        """The first read of a caller that took the reading role in :meth:`_begin` (nothing can have arrived
        before): when the bytes are exactly its final reply, which they nearly always are on TCP and UDP, the
        exchange is done here without the general matching. Otherwise they are matched as usual and None
        sends the caller on to :meth:`_wait`, still counted as a caller.
        """
        lock = self._lock
        data: bytes | None = None
        lost: BaseException | None = None
        interrupt: BaseException | None = None
        try:
            data = self._transport.recv(wait if wait < _POLL else _POLL)
        except Exception as exc:  # noqa: BLE001 - the line failed: _settle_read reports it
            lost = exc
        except BaseException as exc:  # noqa: BLE001 - KeyboardInterrupt: re-raised below
            interrupt = exc
        late = _take_lock(lock)  # always taken, even when the recv itself was interrupted
        interrupt = interrupt or late
        try:
            self._held_read = (data, lost)
            if data and interrupt is None:
                packet = self._session.take_reply(exchange, data)
                if packet is not None:
                    self._held_read = None
                    self._reading = False  # (no _last_rx: it matters only while the parser holds bytes)
                    if self._sleepers:
                        self._cond.notify_all()  # the reading role is free
                    self._leave()
                    return packet
            self._settle_read()
            if interrupt is not None:
                raise interrupt
        except BaseException:
            self._settle_read()
            self._interrupted(exchange)
            self._leave()
            raise
        finally:
            lock.release()
        return None

    def _settle_read(self) -> None:
        """Match what a caller read (``_held_read``) and hand the reading role back (lock held)."""
        held = self._held_read
        if held is None:
            return
        self._held_read = None
        data, lost = held
        if lost is not None:
            self._reading = False
            self._cond.notify_all()
            if not self._stop.is_set():
                error = (
                    lost
                    if isinstance(lost, ConnectionLost)
                    else ConnectionLost(f"reader failed: {lost!r}", device=self.device)
                )
                self._connection_lost(error)  # fails every exchange (the lock is re-entrant)
            return
        if data is None:  # interrupted before anything was read
            self._reading = False
            self._cond.notify_all()
            return
        self._absorb(data)  # _process hands the role back

    def _rescue(self, exchange: Exchange) -> None:
        """Ctrl-C (any BaseException) reached a command between its steps: whatever step it hit, match what
        was read, give the reading role back if this thread holds it and abandon the exchange as a timeout
        does, so no command id and no reader stays taken (issue 13 item 1)."""
        lock = self._lock
        _take_lock(lock)  # a second Ctrl-C here is dropped: the first one is being raised
        try:
            self._settle_read()
            if self._reading == get_ident():
                self._reading = False
                self._cond.notify_all()
            self._interrupted(exchange)
        finally:
            lock.release()

    def _interrupted(self, exchange: Exchange) -> None:
        """A caller waiting for ``exchange`` was interrupted (lock held): abandon it as a timeout does, so
        its late reply is swallowed and its command id is free again (issue: Ctrl-C wedged the id)."""
        if not exchange.finished:
            self._session.abandon(exchange, time.monotonic())
            self._cond.notify_all()
            self._bg.notify()  # the late reply: the reader thread reads it when nobody else does

    def _absorb(self, data: bytes | None) -> None:
        """Match bytes a caller read (lock held); updates among them go to the reader thread's callbacks
        (an update that raced a new subscription)."""
        if data is not None and (found := self._process(data)):
            self._deferred.extend(found)
            self._bg.notify()

    def _leave(self) -> None:
        """A caller is done with its exchange (lock held)."""
        self._callers -= 1
        if not self._callers and self._background_needed():
            self._bg.notify()  # e.g. a pending motion's final reply: nobody waits to read it

    def _wait(
        self,
        exchange: Exchange,
        deadline: float,
        *,
        final: bool,
        abandon: bool = True,
        waited: float | None = None,
        begun: bool = False,
    ) -> Packet:
        """Wait for ``exchange``'s reply (``final``: past E_CMD_PENDING), reading the line when nobody else
        does. ``begun``: the caller was counted by :meth:`_begin`."""
        with self._lock:
            if not begun:
                self._callers += 1
            try:
                return self._await(exchange, deadline, final, abandon, waited)
            except GripperError:
                raise
            except BaseException:  # KeyboardInterrupt, SystemExit: the caller stops waiting
                self._settle_read()
                if self._reading == get_ident():
                    self._reading = False
                    self._cond.notify_all()
                if abandon:
                    self._interrupted(exchange)
                raise
            finally:
                self._leave()

    def _await(
        self, exchange: Exchange, deadline: float, final: bool, abandon: bool, waited: float | None
    ) -> Packet:
        """The wait loop (lock held)."""
        while True:
            state = exchange.state
            if state is ExchangeState.DONE:
                assert exchange.reply is not None
                return exchange.reply
            if state is ExchangeState.PENDING and not final:
                assert exchange.ack is not None
                return exchange.ack
            if state is ExchangeState.FAILED or state is ExchangeState.ABANDONED:
                self._raise_failed(exchange)
            now = time.monotonic()
            if now >= deadline:
                self._timed_out(exchange, now, abandon, waited)
            if self._reading or self._subs or self._stop.is_set() or self._lost is not None:
                if not self._reading:
                    self._bg.notify()  # subscriptions: the reader thread reads (and runs the callbacks)
                self._sleep(deadline - now)
                continue
            # Nobody is reading and no subscription needs the reader thread: read for ourselves.
            self._reading = get_ident()
            lock = self._lock
            data: bytes | None = None
            lost: BaseException | None = None
            interrupt: BaseException | None = None
            try:
                lock.release()
                data = self._transport.recv(min(deadline - now, _POLL))
            except Exception as exc:  # noqa: BLE001 - the line failed: _settle_read reports it
                lost = exc
            except BaseException as exc:  # noqa: BLE001 - KeyboardInterrupt: re-raised below
                interrupt = exc
            late = _take_lock(lock)  # always taken, even when the recv itself was interrupted
            interrupt = interrupt or late
            self._held_read = (data, lost)
            self._settle_read()
            if interrupt is not None:
                raise interrupt

    def _raise_failed(self, exchange: Exchange) -> NoReturn:
        name = command_name(exchange.command)
        if exchange.state is ExchangeState.ABANDONED:
            raise GripperTimeout("abandoned after a timeout", device=self.device, command=name)
        err = exchange.error
        cls = type(err) if isinstance(err, ConnectionLost | ProtocolError) else GripperError
        raise cls(err.message if err else "failed", device=self.device, command=name)

    def _timed_out(self, exchange: Exchange, now: float, abandon: bool, waited: float | None) -> NoReturn:
        state = exchange.state
        if abandon:
            self._session.abandon(exchange, now)
            self._cond.notify_all()
        what = "final reply" if state is ExchangeState.PENDING else "reply"
        after = f" within {waited:g} s" if waited is not None else ""
        raise GripperTimeout(f"no {what}{after}", device=self.device, command=command_name(exchange.command))

    def _check(self, cmd: int, packet: Packet) -> Reply:
        try:
            reply = decode_reply(cmd, packet.payload)
        except ProtocolError as exc:
            raise ProtocolError(exc.message, device=self.device, command=command_name(cmd)) from None
        if not reply.ok:
            code = int(reply.status)
            raise CommandFailed(
                Status.describe(code),
                status=code,
                status_name=reply.status_name,
                device=self.device,
                command=command_name(cmd),
            )
        return reply

    def _call(
        self,
        cmd: int,
        *,
        timeout: float | None = None,
        payload: bytes | None = None,
        internal: bool = False,
        **fields: Any,
    ) -> Reply:
        if self.firmware is not None:  # nothing is refused before the firmware is known
            self._check_supported(cmd)
        if payload is None:
            payload = self._encode(cmd, **fields)
        return self._check(
            cmd, self._exchange(cmd, payload, self.timeout if timeout is None else timeout, internal)
        )

    def _exchange(self, cmd: int, payload: bytes, wait: float, internal: bool = False) -> Packet:
        """Send a request and return its final reply (past E_CMD_PENDING) within ``wait`` seconds."""
        deadline = time.monotonic() + wait
        exchange, lead = self._begin(cmd, payload, deadline, internal=internal)
        try:
            if lead and (packet := self._read_own_reply(exchange, wait)) is not None:
                return packet
            return self._wait(exchange, deadline, final=True, waited=wait, begun=True)
        except GripperError:
            raise
        except BaseException:
            self._rescue(exchange)
            raise

    def _motion(self, cmd: int, wait: bool, timeout: float | None, **fields: Any) -> Pending | None:
        self._check_supported(cmd)
        payload = self._encode(cmd, **fields)
        start = time.monotonic()
        total = self.motion_timeout if timeout is None else timeout
        deadline = start + total
        ack_wait = min(total, self.timeout)
        exchange, lead = self._begin(cmd, payload, start + ack_wait)
        try:
            first = self._read_own_reply(exchange, ack_wait) if lead else None
            if first is None:
                first = self._wait(exchange, start + ack_wait, final=False, waited=ack_wait, begun=True)
        except GripperError:
            raise
        except BaseException:
            self._rescue(exchange)
            raise
        if first.status != Status.E_CMD_PENDING:  # answered at once (an immediate error, or done)
            self._check(cmd, first)
            return None if wait else Pending(self, exchange)
        if not wait:
            return Pending(self, exchange)
        try:
            final = self._wait(exchange, deadline, final=True, waited=total)
        except GripperError:
            raise
        except BaseException:
            self._rescue(exchange)
            raise
        self._check(cmd, final)
        return None

    def request(
        self, cmd: int, payload: bytes = b"", *, timeout: float | None = None, check: bool = False
    ) -> Packet:
        """Send any command with a raw payload; the final reply packet (after E_CMD_PENDING, if any).

        With ``check`` a status other than E_SUCCESS raises CommandFailed; without, the caller reads
        ``packet.status``.
        """
        self._check_supported(cmd)
        packet = self._exchange(cmd, bytes(payload), self.timeout if timeout is None else timeout)
        if check:
            self._check(cmd, packet)
        return packet

    # ------------------------------------------------------------------------------------------- motion

    def home(
        self, direction: int | None = None, *, wait: bool = True, timeout: float | None = None
    ) -> Pending | None:
        """Reference the fingers (20h). direction: None/0 configured default, 1 positive, 2 negative."""
        d = 0 if direction is None else int(direction)
        if d not in (0, 1, 2):
            raise LimitError(
                f"homing direction must be 0, 1 or 2, not {direction!r}",
                device=self.device,
                command=command_name(Cmd.HOMING),
            )
        return self._motion(Cmd.HOMING, wait, timeout, direction=d)

    def preposition(
        self,
        width: float,
        speed: float,
        *,
        relative: bool = False,
        stop_on_block: bool = True,
        wait: bool = True,
        timeout: float | None = None,
    ) -> Pending | None:
        """Move the fingers (21h); width absolute, or an offset when ``relative``."""
        name = command_name(Cmd.PREPOSITION)
        width = _finite("width", width, name, self.device)
        speed = self._speed(speed, name)
        if not relative and width < 0:
            raise LimitError(f"width {width:g} mm is negative", device=self.device, command=name)
        return self._motion(
            Cmd.PREPOSITION,
            wait,
            timeout,
            relative=relative,
            stop_on_block=stop_on_block,
            width=width,
            speed=speed,
        )

    def grip(
        self,
        width: float,
        speed: float,
        *,
        force: float | None = None,
        wait: bool = True,
        timeout: float | None = None,
    ) -> Pending | None:
        """Grip a part of nominal ``width`` (25h); ``force`` sets the force limit (32h) first."""
        name = command_name(Cmd.GRIP)
        width = _finite("width", width, name, self.device)
        speed = self._speed(speed, name)
        if width < 0:
            raise LimitError(f"width {width:g} mm is negative", device=self.device, command=name)
        if force is not None:
            self.set_force_limit(force)
        return self._motion(Cmd.GRIP, wait, timeout, width=width, speed=speed)

    def release(
        self, width: float, speed: float, *, wait: bool = True, timeout: float | None = None
    ) -> Pending | None:
        """Open to ``width`` to release a part (26h)."""
        name = command_name(Cmd.RELEASE)
        width = _finite("width", width, name, self.device)
        speed = self._speed(speed, name)
        if width < 0:
            raise LimitError(f"width {width:g} mm is negative", device=self.device, command=name)
        return self._motion(Cmd.RELEASE, wait, timeout, width=width, speed=speed)

    def _speed(self, speed: float, name: str) -> float:
        speed = _finite("speed", speed, name, self.device)
        if speed <= 0:
            raise LimitError(f"speed must be positive, not {speed:g} mm/s", device=self.device, command=name)
        return speed

    def stop(self, *, timeout: float | None = None) -> None:
        self._call(Cmd.STOP, timeout=timeout)

    def fast_stop(self, *, timeout: float | None = None) -> None:
        self._call(Cmd.FAST_STOP, timeout=timeout)

    def acknowledge_fast_stop(self, key: bytes = b"ack", *, timeout: float | None = None) -> None:
        """Leave FAST STOP (24h); the key is "ack" (docs/protocols.md §1)."""
        self._call(Cmd.ACK_FAST_STOP, timeout=timeout, key=key)

    # ----------------------------------------------------------------------------------------- settings

    def set_acceleration(self, acceleration: float, *, timeout: float | None = None) -> None:
        name = command_name(Cmd.SET_ACCELERATION)
        value = _finite("acceleration", acceleration, name, self.device)
        if value <= 0:
            raise LimitError(
                f"acceleration must be positive, not {value:g}", device=self.device, command=name
            )
        self._call(Cmd.SET_ACCELERATION, timeout=timeout, acceleration=value)

    def acceleration(self, *, timeout: float | None = None) -> float:
        return self._call(Cmd.GET_ACCELERATION, timeout=timeout).fields["acceleration"]

    def set_force_limit(self, force: float, *, timeout: float | None = None) -> None:
        name = command_name(Cmd.SET_FORCE_LIMIT)
        value = _finite("force", force, name, self.device)
        if value <= 0:
            raise LimitError(
                f"force limit must be positive, not {value:g} N", device=self.device, command=name
            )
        self._call(Cmd.SET_FORCE_LIMIT, timeout=timeout, force=value)

    def force_limit(self, *, timeout: float | None = None) -> float:
        return self._call(Cmd.GET_FORCE_LIMIT, timeout=timeout).fields["force"]

    def set_soft_limits(self, minus: float, plus: float, *, timeout: float | None = None) -> None:
        name = command_name(Cmd.SET_SOFT_LIMITS)
        lo = _finite("minus", minus, name, self.device)
        hi = _finite("plus", plus, name, self.device)
        if lo > hi:
            raise LimitError(
                f"soft limit minus {lo:g} mm is above plus {hi:g} mm", device=self.device, command=name
            )
        self._call(Cmd.SET_SOFT_LIMITS, timeout=timeout, minus=lo, plus=hi)

    def soft_limits(self, *, timeout: float | None = None) -> SoftLimits:
        """The soft limits; CommandFailed E_NOT_AVAILABLE when none are set (WSG manual 4.0.x §3.3.6)."""
        return self._call(Cmd.GET_SOFT_LIMITS, timeout=timeout).value

    def clear_soft_limits(self, *, timeout: float | None = None) -> None:
        self._call(Cmd.CLEAR_SOFT_LIMITS, timeout=timeout)

    def set_overdrive(self, on: bool, *, timeout: float | None = None) -> None:
        self._call(Cmd.OVERDRIVE, timeout=timeout, enable=bool(on))

    def tare(self, *, timeout: float | None = None) -> None:
        """Zero the force sensor (38h); E_NOT_AVAILABLE without force-sensing fingers (docs/protocols.md
        §1)."""
        self._call(Cmd.TARE, timeout=timeout)

    # -------------------------------------------------------------------------------------------- state

    def _query(self, cmd: int, timeout: float | None) -> Any:
        """The value of a state query (40h-45h: all firmware has them, so no firmware check)."""
        # A plain query (auto update off) would switch a running subscription off on the device, so while one
        # is active the query repeats its parameters.
        params = self._sub_params.get(cmd)  # one dict read: atomic, no lock needed
        if params is None:
            payload = _PLAIN_QUERY[cmd]
        else:
            payload = encode_request(cmd, auto_update=True, changes_only=params[1], period_ms=params[0])
        packet = self._exchange(cmd, payload, self.timeout if timeout is None else timeout)
        data = packet.payload  # a completed exchange's reply has its status (session)
        if not (data[0] | data[1]):  # E_SUCCESS
            try:
                return reply_value(cmd, data)
            except ProtocolError:
                pass  # _check raises it with the device's name
        return self._check(cmd, packet).value

    def system_state(self, *, timeout: float | None = None) -> SystemFlags:
        return self._query(Cmd.GET_SYSTEM_STATE, timeout)

    def grasping_state(self, *, timeout: float | None = None) -> GraspingState | int:
        return self._query(Cmd.GET_GRASPING_STATE, timeout)

    def grasping_statistics(self, reset: bool = False, *, timeout: float | None = None) -> GraspingStatistics:
        return self._call(Cmd.GET_GRASPING_STATISTICS, timeout=timeout, reset=reset).value

    def width(self, *, timeout: float | None = None) -> float:
        return self._query(Cmd.GET_WIDTH, timeout)

    def speed(self, *, timeout: float | None = None) -> float:
        return self._query(Cmd.GET_SPEED, timeout)

    def force(self, *, timeout: float | None = None) -> float:
        return self._query(Cmd.GET_FORCE, timeout)

    def temperature(self, *, timeout: float | None = None) -> float:
        """Device temperature in °C (46h; firmware 4.x)."""
        return self._call(Cmd.GET_TEMPERATURE, timeout=timeout).fields["temperature"]

    def system_info(self, *, timeout: float | None = None) -> SystemInfo:
        """50h; also records ``firmware``, which decides what the client refuses locally."""
        info: SystemInfo = self._call(Cmd.GET_SYSTEM_INFO, timeout=timeout).value
        self.firmware = info.firmware
        return info

    def system_limits(self, *, timeout: float | None = None) -> SystemLimits:
        limits: SystemLimits = self._call(Cmd.GET_SYSTEM_LIMITS, timeout=timeout).value
        self.limits = limits
        return limits

    def device_tag(self, *, timeout: float | None = None) -> str:
        return self._call(Cmd.GET_DEVICE_TAG, timeout=timeout).fields["tag"]

    def set_device_tag(self, tag: str, *, timeout: float | None = None) -> None:
        name = command_name(Cmd.SET_DEVICE_TAG)
        # WSG manual 4.0.x §3.5.2: at most 64 ASCII characters, no control characters.
        if len(tag) > _MAX_TAG:
            raise LimitError(
                f"device tag of {len(tag)} characters exceeds {_MAX_TAG}", device=self.device, command=name
            )
        if any(not (32 <= ord(c) < 127) for c in tag):
            raise LimitError("device tag must be printable ASCII", device=self.device, command=name)
        self._call(Cmd.SET_DEVICE_TAG, timeout=timeout, tag=tag)

    def loop(self, data: bytes, *, timeout: float | None = None) -> bytes:
        """Echo test (06h): returns what the device looped back."""
        if len(data) > _MAX_LOOP:
            raise LimitError(
                f"loop data of {len(data)} bytes exceeds {_MAX_LOOP}",
                device=self.device,
                command=command_name(Cmd.LOOP),
            )
        return self._call(Cmd.LOOP, timeout=timeout, data=bytes(data)).fields["data"]

    # ----------------------------------------------------------------------------------------- fingers

    def _finger(self, n: int, base: int) -> int:
        if n not in (1, 2):
            raise LimitError(
                f"finger must be 1 or 2, not {n!r}", device=self.device, command=command_name(base)
            )
        return base + (0 if n == 1 else 0x10)

    def finger_info(self, n: int, *, timeout: float | None = None) -> FingerInfo:
        return self._call(self._finger(n, Cmd.GET_FINGER1_INFO), timeout=timeout).value

    def finger_flags(self, n: int, *, timeout: float | None = None) -> FingerFlags:
        return self._call(self._finger(n, Cmd.GET_FINGER1_FLAGS), timeout=timeout).fields["flags"]

    def finger_power(self, n: int, on: bool, *, timeout: float | None = None) -> None:
        """Switch a finger's power (62h/72h); switching on pends about 500 ms (WSG manual 4.0.x §3.6.3)."""
        cmd = self._finger(n, Cmd.FINGER1_POWER)
        self._call(cmd, timeout=max(self.timeout, 2.0) if timeout is None else timeout, power=bool(on))

    def finger_data(self, n: int, *, timeout: float | None = None) -> bytes:
        return self._call(self._finger(n, Cmd.GET_FINGER1_DATA), timeout=timeout).fields["data"]

    # ------------------------------------------------------------------------------------ subscriptions

    def subscribe(
        self,
        cmd: int,
        period_ms: int = 100,
        changes_only: bool = False,
        callback: Callable[[Any], None] | None = None,
        *,
        maxsize: int = 256,
        timeout: float | None = None,
        iter_timeout: float | None = None,
    ) -> Subscription:
        """Auto updates of 40h, 41h, 43h, 44h or 45h every ``period_ms`` (>= 10), or on changes only.

        The first value is the immediate reply. ``iter_timeout`` bounds each wait of the iterator (default:
        wait until a value arrives or the subscription ends).
        """
        cmd = int(cmd)
        name = command_name(cmd)
        if cmd not in AUTO_UPDATE_COMMANDS:
            raise NotSupported(
                "has no auto update (40h, 41h, 43h, 44h, 45h have)", device=self.device, command=name
            )
        if not _MIN_PERIOD_MS <= int(period_ms) <= 0xFFFF:
            raise LimitError(
                f"period must be {_MIN_PERIOD_MS}..65535 ms, not {period_ms!r}",
                device=self.device,
                command=name,
            )
        sub = Subscription(self, cmd, int(period_ms), bool(changes_only), callback, maxsize, iter_timeout)
        with self._cond:
            self._usable(name, False)
            self._subs.setdefault(cmd, []).append(sub)
            self._sub_params[cmd] = (int(period_ms), bool(changes_only))
            self._session.subscribe(cmd)
        try:
            payload = encode_request(
                cmd, auto_update=True, changes_only=changes_only, period_ms=int(period_ms)
            )
            reply = self._call(cmd, timeout=timeout, payload=payload)
        except BaseException:
            self._forget(sub)
            sub._end()
            raise
        sub._deliver(reply.value)
        return sub

    def _forget(self, sub: Subscription) -> bool:
        """Remove ``sub``; True when it was the last one of its command."""
        with self._cond:
            subs = self._subs.get(sub.command, [])
            if sub in subs:
                subs.remove(sub)
            if subs:
                return False
            self._subs.pop(sub.command, None)
            self._sub_params.pop(sub.command, None)
            self._session.unsubscribe(sub.command)
            return True

    def _unsubscribe(self, sub: Subscription, timeout: float | None) -> None:
        if self._forget(sub) and not (self._closing or self._closed or self._lost):
            self._call(sub.command, timeout=timeout, payload=encode_request(sub.command))
