"""What a WSG call hands back when it does not wait: a pending motion, a subscription's stream of values,
state queries answered by callback."""

from __future__ import annotations

import logging
import threading
import time
from collections import deque
from collections.abc import Callable, Iterator, Sequence
from typing import Any, Protocol

from ..closing import Closing
from ..errors import ConnectionLost, GripperError, GripperTimeout
from .commands import command_name
from .exchanges import POLL
from .interrupts import Waiters
from .protocol import Packet
from .reading import Submitted
from .session import Exchange

# What each handle asks of the client that made it (WsgClient / WsgConnection provide these). Declared here,
# not imported from client.py and connection.py, which import this module (issue 32: no import circles).


class MotionOwner(Protocol):
    """What a :class:`Pending` motion needs: its timeouts, STOP, and the wait for the final reply."""

    @property
    def timeout(self) -> float: ...

    @property
    def motion_timeout(self) -> float: ...

    def stop(self, *, timeout: float | None = None) -> None: ...

    def _finish(self, exchange: Exchange, deadline: float, waited: float, abandon: bool = True) -> None: ...


class QueryOwner(Protocol):
    """What :class:`Queries` needs: requests answered by callback, and the query table's payloads/values."""

    @property
    def timeout(self) -> float: ...

    def submit(self, sub: Submitted) -> None: ...

    def withdraw(self, sub: Submitted, error: GripperError | None = None) -> None: ...

    def _query_payload(self, cmd: int) -> bytes: ...

    def _query_value(self, cmd: int, packet: Packet) -> Any: ...


class SubscriptionOwner(Protocol):
    """What a :class:`Subscription` needs: the device's name and a way to end the auto update."""

    @property
    def device(self) -> str: ...

    def _unsubscribe(self, sub: Subscription, timeout: float | None) -> None: ...


__all__ = ["Pending", "Queries", "Subscription"]

log = logging.getLogger(__name__)


class Pending:
    """A motion command that was accepted (E_CMD_PENDING) and whose final reply is still to come."""

    def __init__(self, client: MotionOwner, exchange: Exchange) -> None:
        self._client = client
        self._exchange = exchange
        self.command = exchange.command

    def done(self) -> bool:
        return self._exchange.finished  # one attribute read: no lock needed

    def result(self, timeout: float | None = None) -> None:
        """Wait for the final reply; CommandFailed if it is not E_SUCCESS.

        ``timeout`` defaults to the client's ``motion_timeout``. A timeout here does not abandon the motion:
        ``result`` may be called again; the command id stays busy until the final reply arrives.
        """
        client = self._client
        wait = client.motion_timeout if timeout is None else timeout
        client._finish(self._exchange, time.monotonic() + wait, wait, abandon=False)

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
            client._finish(self._exchange, time.monotonic() + wait, wait)
        except GripperError:
            pass  # the outcome (aborted, failed, timed out) is what result() reports

    def __repr__(self) -> str:
        return f"<Pending {command_name(self.command)} {self._exchange.state.value}>"


class Queries:
    """State queries sent one after another by callback (:meth:`WsgClient.start_queries`), no thread waiting.

    Sequential, not pipelined: the threaded :meth:`WsgClient.queries` reads the same commands in the same
    order, one exchange at a time, and both decode through ``WsgClient._query_value``.
    """

    def __init__(
        self,
        client: QueryOwner,
        cmds: Sequence[int],
        done: Callable[[list[Any] | None, GripperError | None], None],
    ) -> None:
        self._client = client
        self._cmds = cmds
        self._done = done
        self._values: list[Any] = []
        self._current: Submitted | None = None
        self._cancelled = False
        self._over = False

    def send_next(self) -> None:
        cmd = self._cmds[len(self._values)]
        sub = Submitted(cmd, self._client._query_payload(cmd), self._step, self._client.timeout)
        # Set before the request goes out (its reply may come back on the reader at once), and checked after:
        # a cancel() in between sees this request or withdraws it here.
        self._current = sub
        self._client.submit(sub)
        if self._cancelled:
            self._client.withdraw(sub)

    def _step(self, packet: Packet | None, error: GripperError | None) -> None:
        if self._cancelled:
            return
        if packet is not None:
            try:
                self._values.append(self._client._query_value(self._cmds[len(self._values)], packet))
            except GripperError as exc:
                error = exc
        if error is not None:
            self._finish(None, error)
        elif len(self._values) == len(self._cmds):
            self._finish(self._values, None)
        else:
            self.send_next()

    def _finish(self, values: list[Any] | None, error: GripperError | None) -> None:
        if self._over:
            return
        self._over = True
        self._done(values, error)

    def cancel(self) -> None:
        """Give the queries up (idempotent, never blocks): the one outstanding is abandoned (its late reply
        swallowed), no further one is sent, ``done`` is not called any more."""
        self._cancelled = True
        sub = self._current
        if sub is not None:
            self._client.withdraw(sub)


class Subscription(Closing):
    """Auto updates of one state command, as callbacks and as an iterator of decoded values.

    Values go to a bounded queue (``maxsize``); when it is full the OLDEST value is dropped (a consumer that
    falls behind wants the newest state) and ``dropped`` counts the losses (with a callback too: values are
    queued for the iterator either way, so a callback-only user can ignore it). Callbacks run on the client's
    reader thread: keep them short, and do not call the client from them (that would wait for the very
    thread that delivers the reply; the client refuses it with GripperError).
    """

    def __init__(
        self,
        client: SubscriptionOwner,
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
        self._lock = threading.RLock()
        self._cv = Waiters(self._lock)  # get() may be interrupted by Ctrl-C (issue 23 §3)
        self._closed = False
        self._error: GripperError | None = None
        self.dropped = 0
        self.received = 0

    @property
    def closed(self) -> bool:
        return self._closed

    def _deliver(self, value: Any) -> None:
        with self._lock:
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
        with self._lock:
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
        with self._lock:
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
                interrupt = self._cv.wait(POLL if remaining is None else min(remaining, POLL))
                if interrupt is not None:
                    raise interrupt
            return self._queue.popleft()

    def __iter__(self) -> Iterator[Any]:
        return self

    def __next__(self) -> Any:
        with self._lock:
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
