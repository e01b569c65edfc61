"""State queries (40h-45h) of a WSG connection, read by a waiting thread or by callback.

Both ways send the same requests and decode the same replies (the threaded ``WsgClient.queries`` and the
asyncio face's ``start_queries``): a plain query, or, while a subscription of that command runs, one that
repeats its parameters (a plain one would switch the device's auto update off).
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from typing import Any

from ..errors import GripperError, ProtocolError
from .callbacks import Callbacks
from .commands import AUTO_UPDATE_COMMANDS, encode_request, reply_value
from .exchanges import Exchanges
from .handles import Queries
from .protocol import Packet
from .reading import Line, Submitted

__all__ = ["StateReads"]

# The payload of a plain state query (auto update off), encoded once.
_PLAIN_QUERY: dict[int, bytes] = {cmd: encode_request(cmd) for cmd in AUTO_UPDATE_COMMANDS}


class StateReads:
    """The state queries over one connection's blocking and callback sides (see the module docstring); what
    a :class:`~.handles.Queries` asks of its owner."""

    def __init__(self, line: Line, exchanges: Exchanges, callbacks: Callbacks) -> None:
        self._line = line
        self._exchanges = exchanges
        self._callbacks = callbacks

    @property
    def timeout(self) -> float:
        return self._line.timeout

    def submit(self, sub: Submitted) -> None:
        self._callbacks.submit(sub)

    def withdraw(self, sub: Submitted, error: GripperError | None = None) -> None:
        self._callbacks.withdraw(sub, error)

    def query(self, cmd: int, timeout: float | None) -> Any:
        """The value of a state query (40h-45h: all firmware has them, so no firmware check)."""
        packet = self._exchanges.exchange(
            cmd, self._query_payload(cmd), self._line.timeout if timeout is None else timeout
        )
        return self._query_value(cmd, packet)

    def _query_payload(self, cmd: int) -> bytes:
        """A state query's request: plain, or repeating a running subscription's parameters."""
        # A plain query (auto update off) would switch a running subscription off on the device, so while one
        # is active the query repeats its parameters.
        params = self._line.sub_params.get(cmd)  # one dict read: atomic, no lock needed
        if params is None:
            return _PLAIN_QUERY[cmd]
        return encode_request(cmd, auto_update=True, changes_only=params[1], period_ms=params[0])

    def _query_value(self, cmd: int, packet: Packet) -> Any:
        """A state query's reply decoded; CommandFailed or ProtocolError naming the device and command."""
        data = packet.payload  # a completed exchange's reply has its status (session)
        if not (data[0] | data[1]):  # E_SUCCESS
            try:
                return reply_value(cmd, data)
            except ProtocolError:
                pass  # _check raises it with the device's name
        return self._exchanges.check(cmd, packet).value

    def queries(self, cmds: Sequence[int], *, timeout: float | None = None) -> list[Any]:
        """The values of state queries (40h-45h), one after another: what :meth:`start_queries` reads,
        with this thread waiting (and reading its own replies, the cheapest way for a thread)."""
        return [self.query(cmd, timeout) for cmd in cmds]

    def start_queries(
        self, cmds: Sequence[int], done: Callable[[list[Any] | None, GripperError | None], None]
    ) -> Queries:
        """:meth:`queries` with no thread waiting: each query is sent when the previous one's reply came,
        from the reader thread, which then calls ``done(values, None)`` or ``done(None, error)`` (once,
        unless :meth:`Queries.cancel` came first). Each query times out as :meth:`queries`' do (the reader
        keeps the time)."""
        reads = Queries(self, cmds, done)
        reads.send_next()
        return reads
