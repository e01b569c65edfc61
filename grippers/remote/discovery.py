"""What is served: the liveliness tokens ``grippers/<name>`` visible from an endpoint (``grippers probe``),
and whether a name is served already (``grippers serve`` refuses to serve it twice)."""

from __future__ import annotations

from typing import Any

from ..drivers.urls import scheme_of, served_url, zenoh_endpoints
from ..errors import GripperError, URLError
from ..urls import parse_url
from . import protocol

DUPLICATE_WAIT_S = 1.0  # how long refuse_duplicate() listens for another server of the same name


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
    if scheme_of(target) != "zenoh":
        raise URLError(f"{target!r} is not a zenoh:// URL")
    url = parse_url(target)  # the one grammar: drivers/urls.py
    if url.channel:
        return [target]
    params = url.params
    connect = zenoh_endpoints(params.get("connect", ""), f"{target!r}: connect")
    if not connect and "zenoh_config" not in params:
        raise URLError(f"{target!r}: say where to look: zenoh://?connect=tcp/HOST:7447")
    names = served_names(connect, timeout, config_file=params.get("zenoh_config"))
    return [served_url(n, params) for n in names]


def refuse_duplicate(session: Any, name: str, *, declared: bool = False) -> None:
    """Two servers of one name would both answer every query and mix their streams: the second refuses.

    Asked (on the serving ``session``) before anything of ours is declared, and again once everything is
    (``declared``, Server.start): a peer's declarations reach a session that just connected a moment after it
    opened, so the first question alone could miss a server that is there. Answers from our own session do not
    count."""
    from .session import import_zenoh

    zenoh = import_zenoh()
    own = str(session.zid())
    replies = session.get(
        protocol.info_key(name),
        consolidation=zenoh.ConsolidationMode.NONE,
        timeout=DUPLICATE_WAIT_S,
    )
    for reply in replies:
        replier = getattr(reply.replier_id, "zid", None)  # an EntityGlobalId: session and entity
        if reply.ok is None or str(replier) == own or (declared and replier is None):
            continue  # ours, or (once ours is declared) a reply that does not say whose
        try:
            url = str(protocol.decode_json(reply.ok.payload.to_bytes(), "info").get("url", "?"))
        except Exception:
            url = "?"
        raise GripperError(
            f"{name!r} is already served on this Zenoh network (it serves {url}); "
            "stop that server or serve this gripper under another NAME=",
            device=name,
            command="serve",
        )
