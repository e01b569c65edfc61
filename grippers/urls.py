"""The connection-URL grammar, as the API names it.

::

    wsg+tcp://HOST[:PORT]                    wsg+udp://HOST[:PORT][?local_port=N]
    wsg+serial://PORT-OR-PYSERIAL-URL[?baudrate=N&stopbits=2]
    wsg+can://INTERFACE/CHANNEL[?bitrate=N&send_id=0x000&recv_id=0x001]
    stepfoc+can://INTERFACE/CHANNEL[?node=N&bitrate=N]      stepfoc+serial://PORT[?baudrate=N]
    robotiq+serial://PORT[?slave=9]         robotiq+tcp://HOST[:54321][?slave=9]   (54321: a UR forwarder)
    robotiq+tcp://HOST:63352                 (Robotiq's URCap socket; or ?protocol=urcap)
    robotiq+urcap://HOST[:63352]             (a family's own scheme: the same, named as typed)
    schunk+http://HOST[:80]                  schunk+serial://PORT[?slave=12]   (SCHUNK EGU/EGK/EZU)
    sim://PROFILE[?part_width_mm=40&transport=tcp]          (an in-process simulated gripper)
    zenoh://NAME?connect=tcp/HOST:7447                       (a gripper served by `grippers serve`)

The parser itself is ``drivers/urls.py`` (:mod:`grippers.drivers.urls`), where the drivers, the simulators and
the CLI read URLs too: one grammar, no second parser here. Its docstring has the rules.
Query parameters become settings that win over the profile's fields (keyword overrides to
:func:`grippers.open` win over both). Numeric settings are range-checked where a backend takes them
(``grippers/settings.py``, ``RANGES``): a port of 70000 or a timeout of 1e10 s is a :class:`URLError` at open,
before anything is sent.
"""

from __future__ import annotations

import dataclasses
from typing import Any

from grippers.drivers.urls import (
    TRANSPORTS,
    ConnectionURL,
    format_host,
    is_url,
    parse_query,
    refuse_unknown,
    scheme_of,
    to_bool,
    to_float,
    to_int,
)
from grippers.drivers.urls import parse_url as parse_transport_url
from grippers.drivers.urls import with_params as _with_params

from .errors import URLError

__all__ = [
    "TRANSPORTS",
    "ConnectionURL",
    "URLError",
    "format_host",
    "is_url",
    "parse_query",
    "parse_url",
    "refuse_unknown",
    "scheme_of",
    "to_bool",
    "to_float",
    "to_int",
    "with_params",
]


def parse_url(url: str, *, bare_family: str | None = None, listen: bool = False) -> ConnectionURL:
    """The grammar of :func:`grippers.drivers.urls.parse_url`, and a family's own schemes.

    A backend that declares ``url_protocols`` (``{"urcap": "tcp"}``: Robotiq's URCap socket; ``{"http":
    "tcp"}``: a SCHUNK unit's web API) is reached as ``FAMILY+NAME://…``, read as
    ``FAMILY+TRANSPORT://…?protocol=NAME`` and named as typed (``.url``). Every command that takes a URL
    (``open``, ``probe``, ``monitor``, ``sim``, ``selftest``) reads it here, so a scheme ``grippers sim``
    prints is one every other command takes. The drivers' grammar stays the same for every family; only a
    family that says so gets a scheme of its own, and only a family that is installed.
    """
    try:
        return parse_transport_url(url, bare_family=bare_family, listen=listen)
    except URLError as exc:
        refused = exc
    if not isinstance(url, str):
        raise refused
    scheme, sep, rest = url.partition("://")
    family, plus, name = scheme.lower().partition("+")
    if not (sep and plus) or family in ("sim", "zenoh"):
        raise refused
    from .backends import find_backend  # lazily: the table is read only for a scheme the grammar lacks

    backend = find_backend(family)
    base = getattr(backend, "url_protocols", {}).get(name) if backend is not None else None
    if base is None:
        raise refused
    parsed = parse_transport_url(
        f"{family}+{base}://{rest}{'&' if '?' in rest else '?'}protocol={name}",
        bare_family=bare_family,
        listen=listen,
    )
    if parsed.params.get("protocol") != name:
        raise URLError(f"{url}: protocol={parsed.params['protocol']!r} contradicts the scheme {scheme!r}")
    return dataclasses.replace(parsed, url=url)


def with_params(url: str, **values: Any) -> str:
    """:func:`grippers.drivers.urls.with_params` for every URL :func:`parse_url` takes (a family's own
    schemes too)."""
    return _with_params(url, check=parse_url, **values)


def family_scheme(scheme: str) -> bool:
    """Whether ``scheme`` (``wsg+tcp``, ``robotiq+urcap``, ``schunk+http``) names an installed family on one
    of the grammar's transports or on a scheme the family declares (``url_protocols``)."""
    family, plus, transport = scheme.lower().partition("+")
    if not plus:
        return False
    from .backends import available_backends, find_backend

    if family not in available_backends():
        return False
    return transport in TRANSPORTS or transport in getattr(find_backend(family), "url_protocols", {})
