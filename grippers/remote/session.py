"""Zenoh configuration for both sides, in one place: loopback by default, no multicast scouting unless asked.

The only module besides the server and the client that imports ``zenoh``, and only inside functions, so
``import grippers`` and ``grippers --help`` never load it.
"""

from __future__ import annotations

import json
import re
from typing import Any

from ..drivers.urls import zenoh_endpoint
from ..errors import ConnectionLost, URLError
from ..units import to_ms

DEFAULT_LISTEN = "tcp/127.0.0.1:7447"
_RUST_SOURCE = re.compile(r"\s+at\s+\S+\.rs:\d+\.?")  # Zenoh's errors end with the Rust file that raised them


def zenoh_message(exc: BaseException) -> str:
    """A Zenoh error as a user reads it: without the Rust source paths it carries."""
    return _RUST_SOURCE.sub("", str(exc)).strip() or type(exc).__name__


def _reads_back(endpoint: str) -> bool:
    """Whether a listen endpoint's real address is known only once bound: port 0, or every interface."""
    try:
        _proto, host, port = zenoh_endpoint(endpoint, "listen")
    except URLError:
        return False  # Zenoh says what is wrong with it
    return port == 0 or host in ("0.0.0.0", "::")


def import_zenoh() -> Any:
    try:
        import zenoh
    except ImportError:
        raise URLError(
            "serving and zenoh:// URLs need Eclipse Zenoh: pip install 'grippers[remote]'"
        ) from None
    return zenoh


def make_config(
    *,
    mode: str,
    listen: list[str] | None = None,
    connect: list[str] | None = None,
    config_file: str | None = None,
    scout: bool = False,
    lease_s: float | None = None,
) -> Any:
    """A Zenoh config: the user's JSON5 file first (TLS, access control, routers), our settings on top only
    where given, so a file that says where to listen or connect is not overridden by defaults."""
    zenoh = import_zenoh()
    if config_file:
        try:
            config = zenoh.Config.from_file(config_file)
        except Exception as exc:  # zenoh raises ZError for unreadable or invalid files
            raise URLError(f"zenoh config {config_file}: {zenoh_message(exc)}") from None
    else:
        config = zenoh.Config()
    try:
        if not config_file or mode:
            config.insert_json5("mode", json.dumps(mode))
        if listen is not None:
            config.insert_json5("listen/endpoints", json.dumps(listen))
            if any(_reads_back(e) for e in listen):
                # Port 0 or every interface: the real endpoints are read back from our own admin space
                # (own_locators), read-only, to print the URLs that reach us.
                config.insert_json5("adminspace/enabled", "true")
        if connect:
            config.insert_json5("connect/endpoints", json.dumps(connect))
        if not scout:
            # Multicast scouting would announce us on every interface and connect to any peer answering.
            config.insert_json5("scouting/multicast/enabled", "false")
        if lease_s is not None:
            # Zenoh's link lease: how long a silent peer (cable pulled) counts as alive. The control lease
            # relies on it, so it is set to the lease timeout (keep-alives at a quarter of it).
            config.insert_json5("transport/link/tx/lease", str(max(100, int(to_ms(lease_s)))))
            config.insert_json5("transport/link/tx/keep_alive", "4")
    except Exception as exc:
        raise URLError(f"zenoh config: {zenoh_message(exc)}") from None
    return config


def open_session(config: Any, what: str) -> Any:
    zenoh = import_zenoh()
    try:
        return zenoh.open(config)
    except Exception as exc:  # a bad endpoint, a port in use, a TLS file missing
        raise ConnectionLost(f"cannot open a Zenoh session: {zenoh_message(exc)}", device=what) from None


def own_locators(session: Any, timeout: float = 2.0) -> list[str]:
    """The endpoints this session listens on, from its own admin space (port 0 resolved to the real port)."""
    zid = str(session.zid())
    found: list[str] = []
    for reply in session.get(f"@/{zid}/*", timeout=timeout):  # our zid: only we answer
        if reply.ok is None:
            continue
        try:
            doc = json.loads(reply.ok.payload.to_bytes())
        except ValueError:
            continue
        if isinstance(doc, dict) and isinstance(doc.get("locators"), list):
            found += [str(x) for x in doc["locators"]]
    return found
