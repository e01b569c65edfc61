"""``serve(model, listen)``: put a :class:`WsgModel` on a real transport named by a listen URL.

Listen URLs (the simulator's side; it binds to loopback unless a host is given):

- ``tcp://HOST:PORT`` (port 0: any free port; no port: 1000, the WSG default, docs/protocols.md §1)
- ``udp://HOST:PORT`` (no port: 1500)
- ``pty`` (a new pseudo-terminal; ``.url`` names its slave path)
- ``can://INTERFACE/CHANNEL?send_id=..&recv_id=..&bitrate=..&extended=1`` (any python-can interface; the ids
  are the client's: the simulator receives on ``send_id`` (default 0x000) and answers on ``recv_id`` (default
  0x001); standard 11-bit frames unless ``extended=1``; an id the frame format cannot carry is a
  ValueError)

They are read by the one URL grammar (``drivers/urls.py``, with ``listen=True``): a malformed URL or an
unknown parameter is a URLError (also a ValueError), as it is for a client.
"""

from __future__ import annotations

import can

from ...errors import URLError
from ...urls import parse_url, refuse_unknown, scheme_of, shown, to_bool, to_int
from .engine import SimServer
from .model import WsgModel
from .transports import CanSimServer, PtySimServer, TcpSimServer, UdpSimServer

__all__ = ["SimServer", "serve"]

LOOPBACK = "127.0.0.1"
DEFAULT_PORTS = {"tcp": 1000, "udp": 1500}  # docs/protocols.md §1, transport defaults


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
    if scheme_of(listen) not in ("tcp", "udp", "can"):
        raise URLError(
            f"listen URL {shown(listen)}: expected tcp://HOST:PORT, udp://HOST:PORT, pty or can://IF/CHANNEL"
        )
    url = parse_url(listen, bare_family="wsg", listen=True)  # the one grammar: drivers/urls.py
    if url.transport in ("tcp", "udp"):
        refuse_unknown(listen, url.params, ())
        port = url.port if url.port is not None else DEFAULT_PORTS[url.transport]
        cls = TcpSimServer if url.transport == "tcp" else UdpSimServer
        return cls(model, url.host or host, port, time_scale=time_scale)
    assert url.interface  # the grammar refuses a CAN URL without one
    query = url.params
    refuse_unknown(listen, query, ("send_id", "recv_id", "bitrate", "extended"))
    return CanSimServer(
        model,
        interface=url.interface,
        channel=url.channel or "wsg-sim",
        send_id=to_int(query.get("send_id", "0"), "send_id", listen),
        recv_id=to_int(query.get("recv_id", "1"), "recv_id", listen),
        bitrate=to_int(query["bitrate"], "bitrate", listen) if "bitrate" in query else None,
        extended_id=to_bool(query.get("extended", "0"), "extended", listen),
        bus=bus,
        time_scale=time_scale,
    )
