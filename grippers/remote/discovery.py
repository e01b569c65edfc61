"""What is served: the liveliness tokens ``grippers/<name>`` visible from an endpoint (``grippers probe``)."""

from __future__ import annotations

from urllib.parse import quote

from ..errors import URLError
from ..urls import parse_url
from . import protocol


def served_names(connect: list[str], timeout: float = 2.0, *, config_file: str | None = None) -> list[str]:
    """Names of the grippers served where ``connect`` leads; a liveliness query, bounded by ``timeout``."""
    from .session import import_zenoh, make_config, open_session

    zenoh = import_zenoh()
    config = make_config(mode="client", listen=[], connect=connect, config_file=config_file)
    session = open_session(config, "discovery")
    try:
        names = set()
        for reply in session.liveliness().get(protocol.DISCOVERY_KEY, timeout=timeout):
            if reply.ok is not None:
                names.add(str(reply.ok.key_expr).split("/", 1)[1])
        del zenoh
        return sorted(names)
    finally:
        session.close()


def served_urls(target: str, timeout: float = 2.0) -> list[str]:
    """``zenoh://?connect=E``: one ``zenoh://NAME?connect=E`` per served gripper; ``zenoh://NAME?…`` as is."""
    if not target.startswith("zenoh://"):
        raise URLError(f"{target!r} is not a zenoh:// URL")
    url = parse_url(target)  # the one grammar: drivers/urls.py
    if url.channel:
        return [target]
    params = url.params
    connect = [e for e in params.get("connect", "").split(",") if e]
    if not connect and "zenoh_config" not in params:
        raise URLError(f"{target!r}: say where to look: zenoh://?connect=tcp/HOST:7447")
    names = served_names(connect, timeout, config_file=params.get("zenoh_config"))
    rest = "&".join(f"{k}={quote(v, safe='/:,.[]')}" for k, v in params.items())
    return [f"zenoh://{n}?{rest}" for n in names]
