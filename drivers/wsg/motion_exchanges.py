"""Motion exchanges of a WSG connection: the first reply now, the end of the motion later.

A motion command (20h, 21h, 25h, 26h) answers E_CMD_PENDING at once and its final reply when the jaws stop,
seconds later. Between the two its caller may return (``wait=False``: a :class:`~.handles.Pending` waits
later) or wait on, and a Ctrl-C may land anywhere in between: so the caller stays registered with its exchange
from the first reply until it is done with it, and an interrupt there is rescued like one inside an exchange
(:mod:`.exchanges`, whose send, wait and rescue these steps are built from).
"""

from __future__ import annotations

import time
from threading import get_ident

from ..errors import GripperError
from .exchanges import MOTIONS, Exchanges
from .protocol import Packet
from .reading import Line
from .session import Exchange

__all__ = ["MotionSteps"]


class MotionSteps:
    """The steps of a motion command (see the module docstring), built from an :class:`~.exchanges.Exchanges`
    over the same :class:`~.reading.Line`."""

    def __init__(self, line: Line, exchanges: Exchanges) -> None:
        self._line = line
        self._exchanges = exchanges

    def start(self, cmd: int, payload: bytes, timeout: float | None) -> tuple[Exchange, Packet, float, float]:
        """Send a motion command and wait for its first reply: (exchange, first reply, deadline, total).

        The caller stays registered with the exchange (an interrupt before :meth:`finish` or :meth:`done`
        is rescued like one inside them)."""
        start = time.monotonic()
        total = self._line.motion_timeout if timeout is None else timeout
        ack_wait = min(total, self._line.timeout)
        try:
            exchange = self._exchanges.begin(cmd, payload, start + ack_wait)
            first = None
            if self._line.reading == get_ident():
                first = self._exchanges.read_own_reply(exchange, ack_wait)
            if first is None:
                first = self._exchanges.wait(
                    exchange, start + ack_wait, final=False, waited=ack_wait, keep=True
                )
            else:
                with self._line.lock:
                    self._line.callers[get_ident()] = exchange  # kept until the motion's caller is done
        except GripperError:
            raise
        except BaseException:
            self._exchanges.rescue()
            raise
        return exchange, first, start + total, total

    def motion_outstanding(self) -> bool:
        """Whether a motion command (20h, 21h, 25h, 26h) on this connection still waits for its end."""
        return any(exchange.command in MOTIONS for exchange in self._line.session.outstanding())

    def done(self) -> None:
        """The motion's caller returns without waiting for its end (or ends on its first reply)."""
        with self._line.lock:
            self._exchanges.leave()

    def finish(self, exchange: Exchange, deadline: float, waited: float, abandon: bool = True) -> None:
        """Wait for a motion's final reply; CommandFailed unless it is E_SUCCESS."""
        try:
            final = self._exchanges.wait(exchange, deadline, final=True, abandon=abandon, waited=waited)
        except GripperError:
            raise
        except BaseException:
            self._exchanges.rescue(abandon)
            raise
        self._exchanges.check(exchange.command, final)
