"""A WSG connection: the exchange engine over one transport, its reader thread, its lifetime, subscriptions.

The background reader reads only when nobody waits but bytes may still come: subscriptions (their callbacks
always run on it), a pending motion's final reply, a half-received packet, a late reply to swallow, or the
reply of a callback exchange, which it hands back by a call and which may submit the next (see
:mod:`.exchanges` for who reads when, :mod:`.callbacks` for exchanges nobody waits for). The command methods
sit on top (:class:`~.client.WsgClient`).
"""

from __future__ import annotations

import logging
import threading
import time
from collections.abc import Callable
from threading import get_ident
from typing import Any, Self

from can import BusABC

from ..errors import ConnectionLost, GripperError, LimitError, NotSupported
from ..urls import TRANSPORTS, parse_url, refuse_unknown, shown, to_bool, to_float, to_int
from .callbacks import CallbackEngine
from .commands import AUTO_UPDATE_COMMANDS, Cmd, command_name, encode_request
from .exchanges import POLL, SILENT_GAP
from .handles import Subscription
from .motion_exchanges import MotionExchanges
from .reading import Submitted
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

__all__ = ["WsgConnection"]

log = logging.getLogger(__name__)

# The query parameters from_url takes, per transport (the client's framing and ids; the API's settings are
# grippers.open's business).
_FROM_URL_PARAMETERS: dict[str, tuple[str, ...]] = {
    "tcp": (),
    "udp": ("local_port",),
    "serial": ("baudrate", "bytesize", "parity", "stopbits"),
    "can": ("bitrate", "extended", "port", "recv_id", "send_id"),
}
_MIN_PERIOD_MS = 10  # docs/protocols.md §1: auto-update period minimum


class WsgConnection(CallbackEngine, MotionExchanges):
    """One connection to a WSG: requests from any thread, a reader thread for what nobody waits for.

    Both bases extend the one :class:`~.exchanges.ExchangeEngine`: exchanges answered by callback, and
    the steps of a motion command."""

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
        silent_gap: float = SILENT_GAP,
    ) -> None:
        super().__init__(
            transport,
            device=device,
            timeout=timeout,
            motion_timeout=motion_timeout,
            verify_checksum=verify_checksum,
            stale_ttl=stale_ttl,
            stale_final_ttl=stale_final_ttl,
            silent_gap=silent_gap,
        )
        self._sub_params: dict[int, tuple[int, bool]] = {}
        self._reader = threading.Thread(target=self._read_loop, name=f"{self.device} reader", daemon=True)
        self._reader.start()
        self._reader_ident = self._reader.ident

    # ------------------------------------------------------------------------------------------ factories

    @classmethod
    def tcp(
        cls, host: str, port: int = DEFAULT_TCP_PORT, *, connect_timeout: float | None = None, **kw: Any
    ) -> Self:
        wait = connect_timeout if connect_timeout is not None else kw.get("timeout", 5.0)
        return cls(TcpTransport(host, port, connect_timeout=wait), **kw)

    @classmethod
    def udp(
        cls, host: str, port: int = DEFAULT_UDP_PORT, *, local_port: int = DEFAULT_UDP_LOCAL_PORT, **kw: Any
    ) -> Self:
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
    ) -> Self:
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
        port: int | None = None,
        **kw: Any,
    ) -> Self:
        transport = CanTransport(
            bus,
            interface=interface,
            channel=channel,
            bitrate=bitrate,
            send_id=send_id,
            recv_id=recv_id,
            extended_id=extended_id,
            port=port,
        )
        return cls(transport, **kw)

    @classmethod
    def from_url(cls, url: str, **kw: Any) -> Self:
        """``[wsg+]tcp://H:P``, ``[wsg+]udp://H:P?local_port=N``,
        ``[wsg+]serial://PATH-OR-PYSERIAL-URL?baudrate=..``,
        ``[wsg+]can://INTERFACE/CHANNEL?send_id=..&recv_id=..&bitrate=..`` (the simulator's ``.url``), read by
        the one grammar (``drivers/urls.py``). A scheme of another family is a LimitError (not a WSG); a URL
        the grammar refuses, or an unknown parameter, a URLError."""
        scheme = url.partition("://")[0].lower() if isinstance(url, str) else ""
        if scheme.removeprefix("wsg+") not in TRANSPORTS:
            raise LimitError(f"unsupported WSG URL {shown(url)} (tcp, udp, serial or can)")
        u = parse_url(url, bare_family="wsg")
        refuse_unknown(url, u.params, _FROM_URL_PARAMETERS[u.transport])
        query = u.params

        def num(key: str, default: int) -> int:
            return to_int(query[key], key, url) if key in query else default

        if u.transport == "tcp":
            return cls.tcp(u.host or "127.0.0.1", u.port or DEFAULT_TCP_PORT, **kw)
        if u.transport == "udp":
            return cls.udp(
                u.host or "127.0.0.1",
                u.port or DEFAULT_UDP_PORT,
                local_port=num("local_port", DEFAULT_UDP_LOCAL_PORT),
                **kw,
            )
        if u.transport == "serial":
            framing: dict[str, Any] = {"baudrate": num("baudrate", DEFAULT_BAUDRATE)}
            if "parity" in query:
                framing["parity"] = query["parity"]
            if "stopbits" in query:
                framing["stopbits"] = to_float(query["stopbits"], "stopbits", url)
            if "bytesize" in query:
                framing["bytesize"] = num("bytesize", 8)
            assert u.serial_port is not None  # the grammar refuses a serial URL without a port
            return cls.serial(u.serial_port, **framing, **kw)
        return cls.can(
            interface=u.interface,
            channel=u.channel,
            bitrate=num("bitrate", 0) if "bitrate" in query else None,
            send_id=num("send_id", DEFAULT_CAN_SEND_ID),
            recv_id=num("recv_id", DEFAULT_CAN_RECV_ID),
            extended_id=to_bool(query["extended"], "extended", url) if "extended" in query else None,
            port=num("port", 0) if "port" in query else None,
            **kw,
        )

    # -------------------------------------------------------------------------------------------- lifetime

    def close(self, timeout: float | None = None) -> None:
        """Switch auto updates off, announce the disconnect (TCP: 07h, so no FAST STOP), stop the reader.

        Idempotent; never raises for a line that is already gone.
        """
        with self._lock:
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
        with self._lock:
            self._bg.notify()
        if threading.current_thread() is not self._reader:
            self._reader.join(timeout=2.0)
        try:
            self._transport.close()
        except Exception:  # noqa: BLE001 - closing must not fail
            log.debug("closing %s failed", self.device, exc_info=True)
        error = ConnectionLost("client closed", device=self.device)
        with self._lock:
            self._closed = True
            self._session.fail_all(error)
            orphans = self._orphans(error)
            subs = [s for lst in self._subs.values() for s in lst]
            self._subs.clear()
            self._sub_params.clear()
            self._cond.notify_all()
        for sub in subs:
            sub._end()
        for fail, exc in orphans:
            fail(exc)

    @property
    def closed(self) -> bool:
        return self._closed

    @property
    def connection_lost(self) -> ConnectionLost | None:
        return self._lost

    def __enter__(self) -> Self:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()

    def __repr__(self) -> str:
        return f"<{type(self).__name__} {self.device}{' closed' if self._closed else ''}>"

    # ------------------------------------------------------------------------------------------- reader

    def _read_loop(self) -> None:
        """Read when nobody else does but bytes may come; make the deferred calls (subscription values,
        callback replies) and send queued callback requests whose slot came free (:mod:`.callbacks`).

        The calls and sends happen outside the lock and before the next read, and they do not wait for the
        reading role: a callback that submits the next request has it on the line at once."""
        lock = self._lock
        me = get_ident()
        stop = self._stop
        while True:
            sends: list[tuple[Submitted, bytes]] = []
            deliveries: list[tuple[Callable[[Any], None], Any]] = []
            answered = None
            with lock:
                # The usual turn while callback exchanges run: one is out, nobody else reads, nothing else
                # to do: straight to the line (each check below costs a callback round trip time).
                quick = (
                    self._notify
                    and not (self._reading or self._deferred or self._queued or self._callers or self._subs)
                    and self._lost is None
                    and not stop.is_set()
                )
                if not quick:
                    while not stop.is_set():
                        if self._queued and not self._closing:
                            sends = self._start_queued()  # a slot came free (or a barrier is due)
                        if sends or self._deferred or (not self._reading and self._background_needed()):
                            break
                        self._bg.wait(POLL)  # (queued requests: checked again at least every POLL)
                        if self._notify and self._late(time.monotonic()):
                            break  # a callback request's deadline passed: timed out below
                    if stop.is_set() or self._lost is not None:
                        return  # what was opened here fails with the line (close(), _connection_lost)
                    if self._deferred:
                        deliveries, self._deferred = self._deferred, []
                if not (sends or deliveries or self._reading):
                    self._reading = me
                    self._read_line(POLL)
                    answered = self._take_callback_reply()  # else matched as usual: calls go to _deferred
            # Outside the lock, before the next read; a delivery does not wait for the reading role.
            for sub, raw in sends:
                self._call_back(self._send, sub, raw)
            for call, value in deliveries:
                self._call_back(call, value)
            if answered is not None:
                # (it may submit the next request: read at once, above)
                self._call_back(answered[0].reply, answered[1])
            if self._notify:
                self._expire(time.monotonic())  # sent callback requests past their deadline (.callbacks)

    def _call_back(self, call: Callable[..., None], *args: Any) -> None:
        """A call the reader thread makes for others: a bug in it is logged, never the end of the reading
        (whoever waited for it runs into its own timeout)."""
        try:
            call(*args)
        except Exception:  # noqa: BLE001 - see the docstring
            log.exception("%s: a callback raised on the reader thread", self.device)

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
        with self._lock:
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

    def _forget(self, sub: Subscription, *, switched_off: bool = True) -> bool:
        """Remove ``sub``; True when it was the last one of its command. ``switched_off=False``: the device
        still sends its updates until the switch-off request is answered (:meth:`_unsubscribe`)."""
        with self._lock:
            subs = self._subs.get(sub.command, [])
            if sub in subs:
                subs.remove(sub)
            if subs:
                return False
            self._subs.pop(sub.command, None)
            self._sub_params.pop(sub.command, None)
            if switched_off:
                self._session.unsubscribe(sub.command)
            return True

    def _unsubscribe(self, sub: Subscription, timeout: float | None) -> None:
        # The session keeps the command subscribed until the device has answered the switch-off: an update
        # it sent before taking the request (same id, same data) is then an update nobody takes, or the
        # switch-off's reply, never an "unsolicited" packet (benchmark 3 counted one at a switch-off).
        if not self._forget(sub, switched_off=False):
            return
        try:
            if not (self._closing or self._closed or self._lost):
                self._call(sub.command, timeout=timeout, payload=encode_request(sub.command))
        finally:
            with self._lock:
                if sub.command not in self._subs:  # not subscribed again meanwhile
                    self._session.unsubscribe(sub.command)
