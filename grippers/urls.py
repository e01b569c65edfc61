"""The one connection-URL grammar, parsed without I/O.

::

    wsg+tcp://HOST[:PORT]                    wsg+udp://HOST[:PORT][?local_port=N]
    wsg+serial://PORT-OR-PYSERIAL-URL[?baudrate=N&stopbits=2]
    wsg+can://INTERFACE/CHANNEL[?bitrate=N&send_id=0x000&recv_id=0x001]
    stepfoc+can://INTERFACE/CHANNEL[?node=N&bitrate=N]      stepfoc+serial://PORT[?baudrate=N]
    sim://PROFILE[?part_width_mm=40&transport=tcp]          (an in-process simulated gripper)
    zenoh://NAME?connect=tcp/HOST:7447                       (a gripper served by `grippers serve`)

The scheme is ``FAMILY+TRANSPORT``, so a third-party backend brings its own family name. Query parameters
become settings that win over the profile's fields (keyword overrides to :func:`grippers.open` win over both).
Numeric settings are range-checked where a backend takes them (``grippers/settings.py``, ``RANGES``): a port
of 70000 or a timeout of 1e10 s is a :class:`URLError` at open, before anything is sent.
A serial port may itself be a pyserial URL (``wsg+serial://socket://host:4000``, ``wsg+serial://loop://``);
a plain device path is written with its leading slash (``wsg+serial:///dev/ttyUSB0``).
"""

from __future__ import annotations

import ipaddress
from dataclasses import dataclass, field
from typing import Any
from urllib.parse import SplitResult, parse_qsl, unquote, urlsplit

from grippers.drivers.numbers import finite

from .errors import URLError

TRANSPORTS = ("tcp", "udp", "serial", "can")


@dataclass(frozen=True)
class ConnectionURL:
    """A parsed URL: ``family`` and ``transport`` from the scheme, where to go, and the query as settings."""

    url: str
    family: str  # "wsg", "stepfoc", a third-party family, or "sim"
    transport: str  # "tcp", "udp", "serial", "can", or "" for sim://
    host: str | None = None
    port: int | None = None
    serial_port: str | None = None
    interface: str | None = None
    channel: str | None = None
    profile: str | None = None  # sim://PROFILE
    params: dict[str, str] = field(default_factory=dict)

    def location(self) -> dict[str, Any]:
        """Where the device is, for messages and ``grippers probe``."""
        return {
            k: v
            for k, v in {
                "transport": self.transport or "sim",
                "host": self.host,
                "port": self.port,
                "serial_port": self.serial_port,
                "interface": self.interface,
                "channel": self.channel,
                "profile": self.profile,
            }.items()
            if v is not None
        }


def is_url(text: str) -> bool:
    return "://" in text


def parse_url(url: str) -> ConnectionURL:
    if "://" not in url:
        raise URLError(f"{url!r} is not a connection URL (expected FAMILY+TRANSPORT://…, or sim://PROFILE)")
    scheme, rest = url.split("://", 1)
    scheme = scheme.lower()
    if scheme == "sim":
        return _parse_sim(url, rest)
    if scheme == "zenoh":  # zenoh://NAME?connect=tcp/HOST:7447, a served gripper (docs/remote.md)
        return _parse_zenoh(url, rest)
    family, plus, transport = scheme.partition("+")
    if not plus or not family or transport not in TRANSPORTS:
        raise URLError(
            f"{url!r}: scheme {scheme!r} is not FAMILY+TRANSPORT, TRANSPORT one of {', '.join(TRANSPORTS)}"
        )
    if transport == "serial":
        return _parse_serial(url, family, rest)
    parts = _split(url, rest)
    params = _query(url, parts.query)
    if transport in ("tcp", "udp"):
        try:
            host, port = parts.hostname, parts.port
        except ValueError:
            raise URLError(f"{url!r}: bad port") from None
        if not host:
            raise URLError(f"{url!r}: no host")
        if port == 0:
            # Port 0 means "any port" to a socket; connecting there silently went to the profile's default.
            raise URLError(f"{url!r}: port 0 is not a port a gripper listens on (1..65535, or leave it out)")
        # An IPv6 zone is written %25 in a URL (RFC 6874: [fe80::1%25eth0]); sockets want fe80::1%eth0.
        host = unquote(host)
        _check_host(url, host)
        return ConnectionURL(url, family, transport, host=host, port=port, params=params)
    # can://INTERFACE/CHANNEL
    interface = unquote(parts.netloc)
    channel = unquote(parts.path.lstrip("/"))
    if not interface or not channel:
        raise URLError(f"{url!r}: a CAN URL names INTERFACE/CHANNEL, e.g. {family}+can://socketcan/can0")
    return ConnectionURL(url, family, transport, interface=interface, channel=channel, params=params)


def _check_host(url: str, host: str) -> None:
    """Refuse a host name that no resolver could take (``a..b``: an empty label), here, as a URLError,
    instead of a UnicodeError from the IDNA codec when the socket connects."""
    try:
        ipaddress.ip_address(host.partition("%")[0])
        return
    except ValueError:
        pass
    try:
        host.encode("idna")
    except UnicodeError as exc:
        raise URLError(f"{url!r}: {host!r} is not a valid host name ({exc})") from None


def _split(url: str, rest: str) -> SplitResult:
    """urlsplit, with its ValueError (an unclosed ``[`` of an IPv6 host) turned into a URLError."""
    try:
        return urlsplit(f"x://{rest}")
    except ValueError as exc:
        raise URLError(f"{url!r}: {exc}") from None


def _query(url: str, query: str) -> dict[str, str]:
    try:
        return dict(parse_qsl(query, keep_blank_values=True, strict_parsing=bool(query)))
    except ValueError:
        raise URLError(f"{url!r}: malformed query {query!r}") from None


def _parse_serial(url: str, family: str, rest: str) -> ConnectionURL:
    # The port may be a pyserial URL with its own "://"; our parameters follow the last "?".
    port, _, query = rest.rpartition("?") if "?" in rest else (rest, "", "")
    port = unquote(port)
    if not port:
        raise URLError(f"{url!r}: no serial port (e.g. {family}+serial:///dev/ttyUSB0)")
    return ConnectionURL(url, family, "serial", serial_port=port, params=_query(url, query))


def _parse_sim(url: str, rest: str) -> ConnectionURL:
    parts = _split(url, rest)
    profile = unquote(parts.netloc + parts.path).strip("/") or None
    return ConnectionURL(url, "sim", "", profile=profile, params=_query(url, parts.query))


def _parse_zenoh(url: str, rest: str) -> ConnectionURL:
    name, _, query = rest.partition("?")
    served = unquote(name).strip("/") or None
    return ConnectionURL(url, "zenoh", "zenoh", channel=served, params=_query(url, query))


def to_int(value: Any, name: str, url: str = "") -> int:
    """Integers in queries may be decimal or 0x-hex (CAN ids are written in hex)."""
    if isinstance(value, bool):
        raise URLError(f"{url or 'settings'}: {name} must be an integer, not {value!r}")
    if isinstance(value, int):
        return value
    try:
        return int(str(value), 0)
    except ValueError:
        raise URLError(f"{url or 'settings'}: {name} must be an integer, not {value!r}") from None


def to_float(value: Any, name: str, url: str = "") -> float:
    """A finite number: no setting (timeout, time scale, a width) means anything as nan or inf, and a nan
    timeout would make every deadline comparison false, i.e. a wait without end."""
    return finite(value, name, device=url or "settings", error=URLError)


def to_bool(value: Any, name: str, url: str = "") -> bool:
    if isinstance(value, bool):
        return value
    text = str(value).lower()
    if text in ("1", "true", "yes", "on"):
        return True
    if text in ("0", "false", "no", "off"):
        return False
    raise URLError(f"{url or 'settings'}: {name} must be true or false, not {value!r}")
