"""A WSG connection (the exchanger): a Line and the parts sharing it, its reader thread, subscriptions.

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

from ..errors import ConnectionLost, GripperError, LimitError, NotSupported
from .callbacks import Callbacks
from .commands import AUTO_UPDATE_COMMANDS, Cmd, command_name, encode_request
from .exchanges import POLL, Exchanges
from .handles import Subscription
from .motion_exchanges import MotionSteps
from .reading import Line, LineOptions, Submitted
from .transports import Transport

__all__ = ["WsgConnection"]

log = logging.getLogger(__name__)

_MIN_PERIOD_MS = 10  # docs/protocols.md §1: auto-update period minimum


class WsgConnection:
    """One connection to a WSG (the exchanger): requests from any thread, a reader thread for what nobody
    waits for.

    Composed, not inherited (issue 32 §2; httpcore's connection = h11 state machine + network stream): one
    :class:`~.reading.Line` (transport, sans-IO session, lock, reading role) shared by the blocking side
    (:attr:`exchanges`), the callback side (:attr:`callbacks`), the motion steps (:attr:`motions`) and the
    one reader thread here, which also runs the subscriptions (python-can's Notifier)."""

    def __init__(self, transport: Transport, options: LineOptions | None = None) -> None:
        self.line = Line(transport, options or LineOptions())
        self.exchanges = Exchanges(self.line)
        self.callbacks = Callbacks(self.line)
        self.motions = MotionSteps(self.line, self.exchanges)
        self._reader = threading.Thread(
            target=self._read_loop, name=f"{self.line.device} reader", daemon=True
        )
        self._reader.start()
        self.line.reader_ident = self._reader.ident

    @property
    def device(self) -> str:
        return self.line.device

    def outstanding(self) -> list[int]:
        """The command ids whose exchanges still wait for a reply (the sans-IO session's view)."""
        with self.line.lock:
            return [exchange.command for exchange in self.line.session.outstanding()]

    # -------------------------------------------------------------------------------------------- lifetime

    def close(self, timeout: float | None = None) -> None:
        """Switch auto updates off, announce the disconnect (TCP: 07h, so no FAST STOP), stop the reader.

        Idempotent; never raises for a line that is already gone.
        """
        with self.line.lock:
            if self.line.closing or self.line.closed:
                return
            self.line.closing = True
            healthy = self.line.lost is None
        goodbye = min(self.line.timeout, 0.5) if timeout is None else timeout
        if healthy and threading.current_thread() is not self._reader:
            for cmd in list(self.line.sub_params):
                try:
                    self.exchanges.call(cmd, payload=encode_request(cmd), timeout=goodbye, internal=True)
                except GripperError:
                    pass
            if self.line.wire.connection_oriented:
                try:
                    self.exchanges.call(Cmd.DISCONNECT, timeout=goodbye, internal=True)
                except GripperError:
                    pass
        self.line.quit.set()
        with self.line.lock:
            self.line.bg.notify()
        if threading.current_thread() is not self._reader:
            self._reader.join(timeout=2.0)
        try:
            self.line.wire.close()
        except Exception:  # noqa: BLE001 - closing must not fail
            log.debug("closing %s failed", self.line.device, exc_info=True)
        error = ConnectionLost("client closed", device=self.line.device)
        with self.line.lock:
            self.line.closed = True
            self.line.session.fail_all(error)
            orphans = self.line.orphans(error)
            subs = [s for lst in self.line.subs.values() for s in lst]
            self.line.subs.clear()
            self.line.sub_params.clear()
            self.line.cond.notify_all()
        for sub in subs:
            sub._end()
        for fail, exc in orphans:
            fail(exc)

    @property
    def closed(self) -> bool:
        return self.line.closed

    @property
    def connection_lost(self) -> ConnectionLost | None:
        return self.line.lost

    def __enter__(self) -> Self:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()

    def __repr__(self) -> str:
        return f"<{type(self).__name__} {self.line.device}{' closed' if self.line.closed else ''}>"

    # ------------------------------------------------------------------------------------------- reader

    def _read_loop(self) -> None:
        """Read when nobody else does but bytes may come; make the deferred calls (subscription values,
        callback replies) and send queued callback requests whose slot came free (:mod:`.callbacks`).

        The calls and sends happen outside the lock and before the next read, and they do not wait for the
        reading role: a callback that submits the next request has it on the line at once."""
        lock = self.line.lock
        me = get_ident()
        stop = self.line.quit
        while True:
            sends: list[tuple[Submitted, bytes]] = []
            deliveries: list[tuple[Callable[[Any], None], Any]] = []
            answered = None
            with lock:
                # The usual turn while callback exchanges run: one is out, nobody else reads, nothing else
                # to do: straight to the line (each check below costs a callback round trip time).
                quick = (
                    self.line.notify
                    and not (
                        self.line.reading
                        or self.line.deferred
                        or self.line.queued
                        or self.line.callers
                        or self.line.subs
                    )
                    and self.line.lost is None
                    and not stop.is_set()
                )
                if not quick:
                    while not stop.is_set():
                        if self.line.queued and not self.line.closing:
                            sends = self.callbacks.start_queued()  # a slot came free (or a barrier is due)
                        if (
                            sends
                            or self.line.deferred
                            or (not self.line.reading and self.line.background_needed())
                        ):
                            break
                        self.line.bg.wait(POLL)  # (queued requests: checked again at least every POLL)
                        if self.line.notify and self.callbacks.late(time.monotonic()):
                            break  # a callback request's deadline passed: timed out below
                    if stop.is_set() or self.line.lost is not None:
                        return  # what was opened here fails with the line (close(), Line.connection_lost)
                    if self.line.deferred:
                        deliveries, self.line.deferred = self.line.deferred, []
                if not (sends or deliveries or self.line.reading):
                    self.line.reading = me
                    self.line.read_line(POLL)
                    answered = (
                        self.callbacks.take_callback_reply()
                    )  # else matched as usual: calls go to line.deferred
            # Outside the lock, before the next read; a delivery does not wait for the reading role.
            for sub, raw in sends:
                self._call_back(self.callbacks.send, sub, raw)
            for call, value in deliveries:
                self._call_back(call, value)
            if answered is not None:
                # (it may submit the next request: read at once, above)
                self._call_back(answered[0].reply, answered[1])
            if self.line.notify:
                self.callbacks.expire(
                    time.monotonic()
                )  # sent callback requests past their deadline (.callbacks)

    def _call_back(self, call: Callable[..., None], *args: Any) -> None:
        """A call the reader thread makes for others: a bug in it is logged, never the end of the reading
        (whoever waited for it runs into its own timeout)."""
        try:
            call(*args)
        except Exception:  # noqa: BLE001 - see the docstring
            log.exception("%s: a callback raised on the reader thread", self.line.device)

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
                "has no auto update (40h, 41h, 43h, 44h, 45h have)", device=self.line.device, command=name
            )
        if not _MIN_PERIOD_MS <= int(period_ms) <= 0xFFFF:
            raise LimitError(
                f"period must be {_MIN_PERIOD_MS}..65535 ms, not {period_ms!r}",
                device=self.line.device,
                command=name,
            )
        sub = Subscription(self, cmd, int(period_ms), bool(changes_only), callback, maxsize, iter_timeout)
        with self.line.lock:
            self.exchanges.usable(name, False)
            self.line.subs.setdefault(cmd, []).append(sub)
            self.line.sub_params[cmd] = (int(period_ms), bool(changes_only))
            self.line.session.subscribe(cmd)
        try:
            payload = encode_request(
                cmd, auto_update=True, changes_only=changes_only, period_ms=int(period_ms)
            )
            reply = self.exchanges.call(cmd, timeout=timeout, payload=payload)
        except BaseException:
            self._forget(sub)
            sub._end()
            raise
        sub._deliver(reply.value)
        return sub

    def _forget(self, sub: Subscription, *, switched_off: bool = True) -> bool:
        """Remove ``sub``; True when it was the last one of its command. ``switched_off=False``: the device
        still sends its updates until the switch-off request is answered (:meth:`_unsubscribe`)."""
        with self.line.lock:
            subs = self.line.subs.get(sub.command, [])
            if sub in subs:
                subs.remove(sub)
            if subs:
                return False
            self.line.subs.pop(sub.command, None)
            self.line.sub_params.pop(sub.command, None)
            if switched_off:
                self.line.session.unsubscribe(sub.command)
            return True

    def _unsubscribe(self, sub: Subscription, timeout: float | None) -> None:
        # The session keeps the command subscribed until the device has answered the switch-off: an update
        # it sent before taking the request (same id, same data) is then an update nobody takes, or the
        # switch-off's reply, never an "unsolicited" packet (benchmark 3 counted one at a switch-off).
        if not self._forget(sub, switched_off=False):
            return
        try:
            if not (self.line.closing or self.line.closed or self.line.lost):
                self.exchanges.call(sub.command, timeout=timeout, payload=encode_request(sub.command))
        finally:
            with self.line.lock:
                if sub.command not in self.line.subs:  # not subscribed again meanwhile
                    self.line.session.unsubscribe(sub.command)
