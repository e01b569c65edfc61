"""The client of the Robotiq URCap's ASCII socket (TCP 63352 on a UR controller), over a TCP link of the
backend kit (:mod:`grippers.drivers.links`). The lines themselves are :mod:`.urcap_protocol`'s (sans-IO).

``read_status()`` (one GET per field) and ``write_command()`` (one SET of every request field) give the
register view, so the Robotiq backend drives a gripper through the URCap as it does over Modbus.

The socket's replies carry no request id, and a SET's ``ack`` has no line end, so the client keeps the stream
in step itself: one request at a time, and a reply that cannot be this request's (another variable's value, an
``ack`` where a value is due, or the reverse) is a late answer to an earlier request that timed out: it is
dropped and the wait goes on. Bytes that are no reply at all are dropped up to the next reply
(:class:`~.urcap_protocol.ReplyParser`). So one late reply or a burst of garbage costs at most the exchange it
hit, never every later one (issue 43 §5), with or without a reconnection.
"""

from __future__ import annotations

import logging
import threading
import time

from ..dissect import FROM_GRIPPER, TO_GRIPPER
from ..errors import GripperTimeout, ProtocolError
from ..links import ByteLink, TcpLink
from .dissect import log_urcap, wire_debug
from .registers import URCAP_PORT, Command, Status
from .urcap_protocol import STATUS_VARIABLES, Reply, ReplyParser, command_line, get_line, status_of

__all__ = ["UrcapClient"]

log = logging.getLogger(__name__)


class UrcapClient:
    """The register view over the URCap's socket. ``link``: an open link to the socket (tests, another
    transport); by default a :class:`TcpLink` to ``host:port``. gCU is not offered: the status reads None."""

    def __init__(
        self,
        host: str,
        port: int = URCAP_PORT,
        *,
        device: str,
        timeout: float = 1.0,
        slave: int = 9,
        link: ByteLink | None = None,
    ) -> None:
        self.device = device
        self.timeout = timeout
        self.slave = slave
        self.link = link if link is not None else TcpLink(host, port, device=device, timeout=timeout)
        self._lock = threading.Lock()
        self._parser = ReplyParser()
        self.stale = 0  # late replies dropped (answers to requests that had timed out)

    @property
    def alive(self) -> bool:
        return self.link.alive

    @property
    def lost(self) -> bool:
        return self.link.lost

    def _exchange(self, line: bytes, want: str | None, command: str) -> Reply:
        """Send ``line`` and return its reply: ``ack`` (``want`` None) or the value of variable ``want``."""
        with self._lock:
            dropped = self._parser.dropped
            self.link.write(line, command=command)
            if wire_debug():
                log_urcap(self.device, TO_GRIPPER, line)
            deadline = time.monotonic() + self.timeout
            while True:
                try:
                    replies = self.link.read_decoded(self._parser.feed, deadline, command=command)
                except GripperTimeout:
                    garbage = self._parser.dropped - dropped
                    if garbage:
                        raise ProtocolError(
                            f"no answer to {line.decode().strip()!r} within {self.timeout:g} s, only "
                            f"{garbage} bytes that are no URCap reply ({self._parser.garbage!r}...)",
                            device=self.device,
                            command=command,
                        ) from None
                    raise GripperTimeout(
                        f"no answer to {line.decode().strip()!r} within {self.timeout:g} s",
                        device=self.device,
                        command=command,
                    ) from None
                for i, reply in enumerate(replies):
                    if wire_debug():
                        log_urcap(self.device, FROM_GRIPPER, reply.raw.encode())
                    if reply.name != want:  # an answer to an earlier request, late: not this one's
                        self.stale += 1
                        log.debug("%s: dropped a late URCap reply %r", self.device, reply.raw)
                        continue
                    if i + 1 < len(replies):  # not with one request at a time; say so if it happens
                        log.debug("%s: %d unasked URCap replies", self.device, len(replies) - i - 1)
                    if reply.error is not None:
                        raise ProtocolError(reply.error, device=self.device, command=command)
                    return reply

    def get(self, name: str, *, command: str = "status") -> int:
        reply = self._exchange(get_line(name), name, command)
        assert reply.value is not None
        return reply.value

    def read_status(self, *, command: str = "status") -> Status:
        return status_of({name: self.get(name, command=command) for name in STATUS_VARIABLES})

    def write_command(self, cmd: Command, *, command: str = "command") -> None:
        self._exchange(command_line(cmd), None, command)

    def close(self) -> None:
        self.link.close()
