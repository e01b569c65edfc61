"""The client of the Robotiq URCap's ASCII socket (TCP 63352 on a UR controller), over a TCP link of the
backend kit (:mod:`grippers.drivers.links`). The lines themselves are :mod:`.urcap_protocol`'s (sans-IO).

``read_status()`` (one GET per field) and ``write_command()`` (one SET of every request field) give the
register view, so the Robotiq backend drives a gripper through the URCap as it does over Modbus.
"""

from __future__ import annotations

import threading

from ..errors import GripperTimeout, ProtocolError
from ..links import ByteLink, TcpLink
from .registers import URCAP_PORT, Command, Status
from .urcap_protocol import STATUS_VARIABLES, LineParser, Reply, command_line, get_line, status_of

__all__ = ["UrcapClient"]


class UrcapClient:
    """The register view over the URCap's socket. ``link``: an open link to the socket (tests, another
    transport); by default a :class:`TcpLink` to ``host:port``. gCU is not offered: the status reads it 0."""

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
        self._parser = LineParser()

    @property
    def alive(self) -> bool:
        return self.link.alive

    @property
    def lost(self) -> bool:
        return self.link.lost

    def _exchange(self, line: bytes, command: str) -> Reply:
        with self._lock:
            try:
                replies = self.link.exchange(line, self._parser.feed, command=command, timeout=self.timeout)
            except GripperTimeout:
                self._parser = LineParser()  # half a late line must not start the next reply
                raise
        return replies[0]

    def get(self, name: str, *, command: str = "status") -> int:
        reply = self._exchange(get_line(name), command)
        if reply.name != name or reply.value is None:
            raise ProtocolError(f"asked {name}, got {reply.raw!r}", device=self.device, command=command)
        return reply.value

    def read_status(self, *, command: str = "status") -> Status:
        return status_of({name: self.get(name, command=command) for name in STATUS_VARIABLES})

    def write_command(self, cmd: Command, *, command: str = "command") -> None:
        reply = self._exchange(command_line(cmd), command)
        if reply.name is not None:
            raise ProtocolError(f"SET answered {reply.raw!r}, not ack", device=self.device, command=command)

    def close(self) -> None:
        self.link.close()
