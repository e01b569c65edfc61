"""The transports a WSG client opens from plain parameters or from a URL (the simulator's ``.url``).

Kept apart from the client so that the client is only its commands over an exchanger: this module knows the
transports' defaults and the one URL grammar (``drivers/urls.py``), the client knows neither.
"""

from __future__ import annotations

from typing import Any

from ..errors import LimitError
from ..urls import TRANSPORTS, parse_url, refuse_unknown, scheme_of, shown, to_bool, to_float, to_int
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

__all__ = ["transport_from_url"]

# The query parameters a URL may carry, per transport (the client's framing and ids; the API's settings are
# grippers.open's business).
_FROM_URL_PARAMETERS: dict[str, tuple[str, ...]] = {
    "tcp": (),
    "udp": ("local_port",),
    "serial": ("baudrate", "bytesize", "parity", "stopbits"),
    "can": ("bitrate", "extended", "port", "recv_id", "send_id"),
}


def transport_from_url(url: str, *, connect_timeout: float) -> Transport:
    """``[wsg+]tcp://H:P``, ``[wsg+]udp://H:P?local_port=N``,
    ``[wsg+]serial://PATH-OR-PYSERIAL-URL?baudrate=..``,
    ``[wsg+]can://INTERFACE/CHANNEL?send_id=..&recv_id=..&bitrate=..``, read by the one grammar
    (``drivers/urls.py``). A scheme of another family is a LimitError (not a WSG); a URL the grammar
    refuses, or an unknown parameter, a URLError."""
    if scheme_of(url).removeprefix("wsg+") not in TRANSPORTS:
        raise LimitError(f"unsupported WSG URL {shown(url)} (tcp, udp, serial or can)")
    u = parse_url(url, bare_family="wsg")
    refuse_unknown(url, u.params, _FROM_URL_PARAMETERS[u.transport])
    query = u.params

    def num(key: str, default: int) -> int:
        return to_int(query[key], key, url) if key in query else default

    if u.transport == "tcp":
        return TcpTransport(
            u.host or "127.0.0.1", u.port or DEFAULT_TCP_PORT, connect_timeout=connect_timeout
        )
    if u.transport == "udp":
        return UdpTransport(
            u.host or "127.0.0.1",
            u.port or DEFAULT_UDP_PORT,
            local_port=num("local_port", DEFAULT_UDP_LOCAL_PORT),
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
        return SerialTransport(u.serial_port, **framing)
    return CanTransport(
        None,
        interface=u.interface,
        channel=u.channel,
        bitrate=num("bitrate", 0) if "bitrate" in query else None,
        send_id=num("send_id", DEFAULT_CAN_SEND_ID),
        recv_id=num("recv_id", DEFAULT_CAN_RECV_ID),
        extended_id=to_bool(query["extended"], "extended", url) if "extended" in query else None,
        port=num("port", 0) if "port" in query else None,
    )
