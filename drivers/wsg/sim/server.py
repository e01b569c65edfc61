"""``serve(model, listen)``: put a :class:`WsgModel` on a real transport named by a listen URL.

Listen URLs (the simulator's side; it binds to loopback unless a host is given):

- ``tcp://HOST:PORT`` (port 0: any free port; no port: 1000, the WSG default, docs/protocols.md §1)
- ``udp://HOST:PORT`` (no port: 1500)
- ``pty`` (a new pseudo-terminal; ``.url`` names its slave path)
- ``can://INTERFACE/CHANNEL?send_id=..&recv_id=..&bitrate=..&extended=1`` (any python-can interface; the ids
  are the client's: the simulator receives on ``send_id`` (default 0x000) and answers on ``recv_id`` (default
  0x001); standard 11-bit frames unless ``extended=1``; an id the frame format cannot carry is a ValueError)
"""

from __future__ import annotations

from urllib.parse import parse_qs, urlsplit

import can

from .engine import SimServer
from .model import WsgModel
from .transports import CanSimServer, PtySimServer, TcpSimServer, UdpSimServer

__all__ = ["SimServer", "serve"]

LOOPBACK = "127.0.0.1"
DEFAULT_PORTS = {"tcp": 1000, "udp": 1500}  # docs/protocols.md §1, transport defaults


def _int(text: str) -> int:
    return int(text, 0)


def serve(
    model: WsgModel,
    listen: str,
    *,
    time_scale: float = 1.0,
    host: str = LOOPBACK,
    bus: can.BusABC | None = None,
) -> SimServer:
    """Start serving ``model`` on ``listen`` in a background thread; close the returned server when done.

    ``host`` is used when the URL names none. ``bus`` lends an already open python-can bus to a ``can://``
    listener (it is then not shut down on close).
    """
    if listen in ("pty", "pty://"):
        return PtySimServer(model, time_scale=time_scale)
    parts = urlsplit(listen)
    scheme = parts.scheme.lower()
    if scheme in ("tcp", "udp"):
        address = parts.hostname or host
        port = parts.port if parts.port is not None else DEFAULT_PORTS[scheme]
        cls = TcpSimServer if scheme == "tcp" else UdpSimServer
        return cls(model, address, port, time_scale=time_scale)
    if scheme == "can":
        interface = parts.netloc
        channel = parts.path.lstrip("/") or "wsg-sim"
        if not interface:
            raise ValueError(f"listen URL {listen!r} names no python-can interface (can://INTERFACE/CHANNEL)")
        query = {k: v[-1] for k, v in parse_qs(parts.query).items()}
        unknown = set(query) - {"send_id", "recv_id", "bitrate", "extended"}
        if unknown:
            raise ValueError(f"listen URL {listen!r}: unknown parameter(s) {', '.join(sorted(unknown))}")
        return CanSimServer(
            model,
            interface=interface,
            channel=channel,
            send_id=_int(query.get("send_id", "0")),
            recv_id=_int(query.get("recv_id", "1")),
            bitrate=_int(query["bitrate"]) if "bitrate" in query else None,
            extended_id=query.get("extended", "0").lower() in ("1", "true", "yes"),
            bus=bus,
            time_scale=time_scale,
        )
    raise ValueError(
        f"listen URL {listen!r}: expected tcp://HOST:PORT, udp://HOST:PORT, pty or can://IF/CHANNEL"
    )
