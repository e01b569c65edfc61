"""The one connection-URL grammar of the library, parsed without I/O.

::

    wsg+tcp://HOST[:PORT]                    wsg+udp://HOST[:PORT][?local_port=N]
    wsg+serial://PORT-OR-PYSERIAL-URL[?baudrate=N&stopbits=2]
    wsg+can://INTERFACE/CHANNEL[?bitrate=N&send_id=0x000&recv_id=0x001]
    stepfoc+can://INTERFACE/CHANNEL[?node=N&bitrate=N]      stepfoc+serial://PORT[?baudrate=N]
    robotiq+serial://PORT[?slave=9]         robotiq+tcp://HOST[:54321][?slave=9]   (54321: a UR forwarder)
    robotiq+tcp://HOST:63352                 (Robotiq's URCap socket; or ?protocol=urcap)
    sim://PROFILE[?part_width_mm=40&transport=tcp]          (an in-process simulated gripper)
    zenoh://NAME?connect=tcp/HOST:7447                       (a gripper served by `grippers serve`)

It lives in ``drivers`` so that the drivers, the simulators' listen URLs, the CLI and :mod:`grippers.urls`
(the API's face of it) all read a URL the same way: copies of this parser had drifted (one kept a
``#fragment``'s text, one silently dropped a ``bitrate=`` left blank, one took ``tcp://h:1000/x`` for
``h:1000``).

The rules, each one a :class:`~grippers.drivers.errors.URLError` naming the URL when broken:

- The scheme is ``FAMILY+TRANSPORT`` (a third-party backend brings its own family name). Where a caller knows
  the family (a driver's ``from_url``, a simulator's listen URL) it may accept the bare transport (``tcp://``).
- A host is a name, an IPv4 address or a bracketed IPv6 address (``[fe80::1%25eth0]``: the zone is written
  ``%25``, RFC 6874, and handed to the socket as ``fe80::1%eth0``); the port is 1..65535 (0, "any free port",
  only in a listen URL). A user name, a path or a fragment after the host is refused, never silently dropped.
- A CAN URL is ``INTERFACE/CHANNEL``; everything after the first ``/`` is the channel, so a multicast channel
  may be an IPv6 address full of colons. The interfaces whose channel is a serial port
  (:data:`SERIAL_CHANNEL_INTERFACES`: python-can's slcan, serial, seeedstudio, robotell) keep a device path's
  leading slash: ``stepfoc+can://slcan/dev/ttyACM0`` and ``slcan//dev/ttyACM0`` both open ``/dev/ttyACM0``
  (the first form, the documented one, opened the relative ``dev/ttyACM0``); ``slcan/COM3``, a pyserial URL
  (``slcan/socket://h:4000``) and an explicitly relative ``./x`` stay as written. Every other interface's
  channel is a name or an address (``socketcan/can0``, ``udp_multicast/239.74.163.2``, ``pcan/PCAN_USBBUS1``)
  and is never given one.
- A serial port may itself be a pyserial URL (``wsg+serial://socket://host:4000``, ``wsg+serial://loop://``);
  our parameters follow the LAST ``?``. A device path is written with its leading slash
  (``wsg+serial:///dev/ttyUSB0``).
- The query is ``key=value`` pairs joined by ``&``, percent-decoded; a field without ``=``, an empty field or
  an empty key is malformed. A key given twice with two different values is refused (which one did the user
  mean? On a bus, the wrong ``node`` drives another gripper); the same value twice is accepted.
- Host, interface, channel, profile, serial port and query values are percent-decoded; a control character
  (raw or decoded) anywhere is refused: a newline in a URL is an injection, not a device name.

Every module that reads a URL, an address or a query calls one of this module's readers (:func:`parse_url`,
:func:`scheme_of`, :func:`parse_address`, :func:`zenoh_endpoints`, :func:`web_fields`, :func:`on_transport`,
...), never the string splitting under them (issue 40 §6; tests/test_readable_tree.py names the exceptions).
"""

from __future__ import annotations

import difflib
import ipaddress
import re
from collections.abc import Callable, Iterable, Mapping
from dataclasses import dataclass, field
from typing import Any
from urllib.parse import parse_qsl, quote, unquote, unquote_plus, urlencode, urlsplit, urlunsplit

from .errors import URLError
from .numbers import finite

__all__ = [
    "append_params",
    "BUS_OPTIONS",
    "SERIAL_CHANNEL_INTERFACES",
    "TRANSPORTS",
    "ConnectionURL",
    "URLError",
    "bus_options",
    "check_endpoints",
    "encode_query",
    "format_host",
    "is_url",
    "on_transport",
    "parse_address",
    "parse_query",
    "parse_url",
    "refuse_unknown",
    "same_origin",
    "scheme_of",
    "served_url",
    "shown",
    "to_bool",
    "to_float",
    "to_int",
    "web_fields",
    "web_host",
    "web_origin",
    "web_target",
    "with_params",
    "with_query",
    "without_secrets",
    "zenoh_endpoint",
    "zenoh_endpoints",
    "zenoh_port",
]

TRANSPORTS = ("tcp", "udp", "serial", "can")
# python-can 4.6's interfaces whose channel is a serial port (pyserial's ``serial_for_url`` or ``Serial``:
# can/interfaces/slcan.py, serial/serial_can.py, seeedstudio/seeedstudio.py, robotell.py). The others take an
# interface name (socketcan), an address (udp_multicast, socketcand), a device index or a vendor channel.
SERIAL_CHANNEL_INTERFACES = frozenset({"slcan", "serial", "seeedstudio", "robotell"})
_FAMILY = re.compile(r"[a-z][a-z0-9_-]*\Z")
_CONTROL = re.compile(r"[\x00-\x1f\x7f]")
_SHOWN = 200  # characters of a URL quoted in an error message: a megabyte of hostile text stays one line


@dataclass(frozen=True)
class ConnectionURL:
    """A parsed URL: ``family`` and ``transport`` from the scheme, where to go, and the query as settings."""

    url: str
    family: str  # "wsg", "stepfoc", a third-party family, "sim" or "zenoh"
    transport: str  # "tcp", "udp", "serial", "can", "zenoh", or "" for sim://
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


def scheme_of(text: object) -> str:
    """The scheme of a URL in lower case, as :func:`parse_url` reads it (``wsg+tcp``, ``can``, ``sim``);
    ``""`` for anything that is not a URL. For a caller that picks a reader by the scheme before parsing."""
    return text.partition("://")[0].lower() if isinstance(text, str) and is_url(text) else ""


def on_transport(url: str, protocols: Mapping[str, str]) -> tuple[str, str | None]:
    """A URL whose scheme names a protocol of ``protocols`` (``{"urcap": "tcp"}``: ``urcap://h:p`` or
    ``robotiq+urcap://h:p``) rewritten onto that protocol's transport (``tcp://h:p``), with the protocol's
    name; any other URL as given, with None. For a simulator's listen URL in a family's own scheme (the
    Robotiq URCap socket, a SCHUNK unit's ``http://``), which the grammar then reads as usual."""
    scheme, sep, rest = url.partition("://")
    family, plus, name = scheme.lower().rpartition("+")
    base = protocols.get(name) if sep else None
    if base is None:
        return url, None
    return f"{family}{plus}{base}://{rest}", name


def parse_address(text: str, *, listen: bool = False) -> tuple[str | None, int]:
    """``HOST:PORT`` without a scheme (``127.0.0.1:8000``, ``[::1]:7447``, ``gripper.local:1000``) by the
    rules of a URL's host and port: an IPv6 address in brackets (its zone as ``%25``), the port 0..65535
    and never left out. ``listen``: an address to bind, where port 0 (any free port) and an empty host
    (``:8000``, None: the caller's default) are allowed."""
    if not isinstance(text, str):
        raise URLError(f"{text!r} is not an address (HOST:PORT)")
    _no_control(text, text, "address")
    host, port = _host_port(text, text, listen)
    if port is None:
        raise URLError(f"{shown(text)}: an address is HOST:PORT, with the port")
    return host, port


def shown(url: str) -> str:
    """The URL as error messages quote it."""
    text = repr(url)
    return text if len(text) <= _SHOWN else f"{text[:_SHOWN]}... ({len(url)} characters)"


def parse_url(url: str, *, bare_family: str | None = None, listen: bool = False) -> ConnectionURL:
    """Parse ``url`` by the grammar above.

    ``bare_family``: a bare transport scheme (``tcp://``) is read as that family's (a driver or a simulator
    knows which protocol it speaks). ``listen``: a simulator's listen URL, where the host may be left out
    (the caller binds loopback), port 0 asks for any free port and a CAN channel may be left out.
    """
    if not isinstance(url, str):
        raise URLError(f"{url!r} is not a connection URL (a str)")
    _no_control(url, url, "URL")
    if "://" not in url:
        raise URLError(
            f"{shown(url)} is not a connection URL (expected FAMILY+TRANSPORT://…, or sim://PROFILE)"
        )
    scheme, rest = url.split("://", 1)
    scheme = scheme.lower()
    if scheme == "sim":
        return _parse_sim(url, rest)
    if scheme == "zenoh":  # zenoh://NAME?connect=tcp/HOST:7447, a served gripper (docs/remote.md)
        return _parse_zenoh(url, rest)
    family, plus, transport = scheme.partition("+")
    if not plus and bare_family is not None and scheme in TRANSPORTS:
        family, transport = bare_family, scheme
    elif not plus or not _FAMILY.match(family) or transport not in TRANSPORTS:
        raise URLError(
            f"{shown(url)}: scheme {scheme[:40]!r} is not FAMILY+TRANSPORT, "
            f"TRANSPORT one of {', '.join(TRANSPORTS)}"
        )
    if transport == "serial":
        return _parse_serial(url, family, rest)
    if "#" in rest:
        raise URLError(f"{shown(url)}: a connection URL has no #fragment (write # in a value as %23)")
    base, _, query = rest.partition("?")
    params = parse_query(url, query)
    if transport in ("tcp", "udp"):
        netloc, _, path = base.partition("/")
        if path:
            raise URLError(f"{shown(url)}: a {transport} URL is HOST[:PORT], with no path ({path[:40]!r})")
        host, port = _host_port(url, netloc, listen)
        return ConnectionURL(url, family, transport, host=host, port=port, params=params)
    # can://INTERFACE/CHANNEL
    raw_interface, _, raw_channel = base.partition("/")
    if "[" in raw_interface or "]" in raw_interface:
        raise URLError(f"{shown(url)}: a CAN interface is a python-can interface name, not {raw_interface!r}")
    interface = _decoded(url, raw_interface, "interface")
    channel = _decoded(url, raw_channel, "channel")
    if not interface or not (channel or listen):
        raise URLError(f"{shown(url)}: a CAN URL names INTERFACE/CHANNEL, e.g. {family}+can://socketcan/can0")
    channel = _device_path(interface, channel)
    return ConnectionURL(url, family, transport, interface=interface, channel=channel or None, params=params)


def _device_path(interface: str, channel: str) -> str:
    """A serial-line adapter's channel with the leading slash the URL's ``/`` separator took away.

    ``slcan/dev/ttyACM0``: the first ``/`` separates interface and channel, so the channel reads
    ``dev/ttyACM0``, a path relative to the working directory that no user means. A channel already absolute
    (``slcan//dev/ttyACM0``), a port name without a slash (``COM3``, ``ttyACM0``), a pyserial URL
    (``socket://h:4000``) or an explicitly relative path (``./x``) is left as written.
    """
    if interface.lower() not in SERIAL_CHANNEL_INTERFACES or "/" not in channel:
        return channel
    if channel.startswith(("/", "./", "../")) or "://" in channel:
        return channel
    return "/" + channel


def parse_query(url: str, query: str) -> dict[str, str]:
    """``k=v&k2=v2`` as a dict of percent-decoded strings (the rules in the module's docstring)."""
    if not query:
        return {}
    try:
        pairs = parse_qsl(query, keep_blank_values=True, strict_parsing=True)
    except ValueError:
        raise URLError(
            f"{shown(url)}: malformed query {query[:80]!r} (expected key=value&key=value)"
        ) from None
    params: dict[str, str] = {}
    for key, value in pairs:
        if not key:
            raise URLError(f"{shown(url)}: malformed query {query[:80]!r} (a value without a key)")
        _no_control(url, key, "query key")
        _no_control(url, value, key)
        if key in params and params[key] != value:
            raise URLError(f"{shown(url)}: {key} given twice ({params[key][:40]!r} and {value[:40]!r})")
        params[key] = value
    return params


BUS_OPTIONS = ("bitrate", "port")


def web_origin(text: str) -> tuple[str, str] | None:
    """An HTTP ``Origin`` (``http://h:p``) as ``(scheme, netloc)``; None unless it is http(s) with a host.

    The panel compares it with the request's ``Host`` (grippers/panel/security.py); it lives here so that the
    standard library's URL parsers are called by this module alone (tests/api/test_one_url_grammar.py)."""
    try:
        parts = urlsplit(text)
    except ValueError:  # an unbalanced [ in the host
        return None
    if parts.scheme not in ("http", "https") or not parts.netloc:
        return None
    return parts.scheme, parts.netloc


def web_host(value: str) -> str:
    """The host of an HTTP ``Host`` header (``[::1]:8000``, ``localhost:8000``, ``10.0.0.2``), without its
    port or an IPv6 address's brackets; a bare IPv6 address (``::1``) as it is."""
    if value.startswith("["):
        return value[1 : value.find("]")] if "]" in value else value
    return value.rsplit(":", 1)[0] if value.count(":") == 1 else value


def same_origin(origin: str, host: str) -> bool:
    """Whether an HTTP ``Origin`` (``http://h:p``) names the host and port a request was sent to (its
    ``Host`` header), the scheme's default port standing for a port left out (the panel's CSRF check)."""
    parts = web_origin(origin)
    if parts is None:
        return False
    scheme, netloc = parts
    default = "443" if scheme == "https" else "80"
    ours = host if ":" in host.rsplit("]", 1)[-1] else f"{host}:{default}"
    theirs = netloc if ":" in netloc.rsplit("]", 1)[-1] else f"{netloc}:{default}"
    return ours.lower() == theirs.lower()


def web_target(target: str) -> tuple[str, dict[str, str]]:
    """An HTTP request target (``/adi/data.json?inst=0x0040``) as (path, fields): :func:`web_fields`."""
    path, _, query = target.partition("?")
    return path, web_fields(query, target)


def web_fields(text: str, what: str = "web request") -> dict[str, str]:
    """An HTTP query string or an HTML form body (``k=v&k2=v2``) as fields by the grammar's query rules;
    a malformed one carries no fields (a web server answers it: it does not raise)."""
    try:
        return parse_query(what, text)
    except URLError:
        return {}


def bus_options(url: ConnectionURL) -> dict[str, int]:
    """The python-can bus options a CAN URL's query carries, for a command that opens the bus itself
    (``grippers probe``, ``grippers monitor``), read the way the backends read them.

    ``port``: python-can's ``udp_multicast`` bus is one UDP port for every group on Linux, so a bus of one's
    own is a port of one's own; a probe or monitor that dropped ``?port=`` watched python-can's default port
    and reported another process's nodes as found (issue 33 §3). ``bitrate`` is left out for the interfaces
    that have none (virtual, udp_multicast)."""
    options = {k: to_int(url.params[k], k, url.url) for k in BUS_OPTIONS if k in url.params}
    if "port" in options and not 1 <= options["port"] <= 65535:
        raise URLError(f"{shown(url.url)}: port must lie within 1..65535, not {options['port']}")
    if "bitrate" in options and options["bitrate"] <= 0:
        raise URLError(f"{shown(url.url)}: bitrate must be above 0, not {options['bitrate']}")
    if (url.interface or "").lower() in ("virtual", "udp_multicast"):
        options.pop("bitrate", None)
    return options


_SECRET_WORDS = ("key", "password", "passwd", "secret", "token", "cert")


def without_secrets(url: str) -> str:
    """``url`` as it may be shown to others (``/diagnostics``, logs): no user info, and the values of query
    settings whose names look like secrets (TLS keys, passwords, tokens) replaced by ``***``."""
    parts = urlsplit(url)
    netloc = parts.netloc.rsplit("@", 1)[-1]
    query = [
        (k, "***" if any(w in k.lower() for w in _SECRET_WORDS) else v)
        for k, v in parse_qsl(parts.query, keep_blank_values=True)
    ]
    return urlunsplit((parts.scheme, netloc, parts.path, urlencode(query, safe="/:,"), parts.fragment))


def with_params(url: str, *, check: Callable[[str], Any] | None = None, **values: Any) -> str:
    """``url`` with these query parameters set, first and in this order; the others kept as written.

    For a URL the CLI hands back to the user (``grippers settings --node-id`` names the node's new URL).
    ``check``: the parser that must accept ``url`` first (:func:`grippers.urls.parse_url` takes a family's own
    schemes too); this module's :func:`parse_url` by default.
    """
    (check or parse_url)(url)  # only a URL of the grammar is rewritten
    base, query = _split_query(url)
    kept = [f for f in query.split("&") if f and unquote_plus(f.partition("=")[0]) not in values]
    ours = [f"{quote(k, safe='')}={quote(str(v), safe='/:,.')}" for k, v in values.items()]
    return f"{base}?{'&'.join(ours + kept)}"


def encode_query(params: Mapping[str, Any]) -> str:
    """``k=v&k2=v2``, percent-encoded, as :func:`parse_query` reads it back (``""`` for no parameters)."""
    return urlencode({k: str(v) for k, v in params.items()})


def with_query(url: str, params: Mapping[str, Any]) -> str:
    """``url`` with its query replaced by ``params`` (none: no ``?``), by the grammar's rule of where a
    query starts (a serial URL's at its last ``?``)."""
    query = encode_query(params)
    return _split_query(url)[0] + (f"?{query}" if query else "")


def append_params(url: str, params: Mapping[str, Any]) -> str:
    """``url`` with ``params`` added after the query it has (``gripper_sim``'s ``&profile=``, a simulated
    bus's ``&port=`` on every node's URL)."""
    base, query = _split_query(url)
    return f"{base}?{'&'.join(q for q in (query, encode_query(params)) if q)}"


def _split_query(url: str) -> tuple[str, str]:
    """(base, query) of ``url``: a serial port may be a pyserial URL with a ``?`` of its own, so a serial
    URL's query follows its last ``?``, every other's its first."""
    serial = scheme_of(url).endswith("+serial")
    base, _, query = url.rpartition("?") if serial and "?" in url else url.partition("?")
    return base, query


def refuse_unknown(
    url: str,
    params: Iterable[str],
    known: Iterable[str],
    *,
    what: str = "parameter(s)",
    known_as: str = "known",
) -> None:
    """A misspelt parameter is an error, not a default silently used instead of what the user wrote.

    The message names each unknown one, the closest known name where there is one (``nod``: did you mean
    ``node``?), and every known name."""
    names = sorted(set(known))
    unknown = sorted(set(params) - set(names))
    if not unknown:
        return
    hints = []
    for name in unknown:
        close = difflib.get_close_matches(name, names, n=1, cutoff=0.6)
        if close:
            hints.append(f"{name}: did you mean {close[0]}?")
    hint = f"; {'; '.join(hints)}" if hints else ""
    raise URLError(
        f"{shown(url)}: unknown {what} {', '.join(unknown)}{hint} ({known_as}: {', '.join(names) or 'none'})"
    )


def format_host(host: str, port: int | None = None) -> str:
    """``HOST[:PORT]`` as a URL writes it: an IPv6 address in brackets, its zone as ``%25``."""
    text = f"[{host.replace('%', '%25')}]" if ":" in host else host
    return text if port is None else f"{text}:{port}"


def _host_port(url: str, netloc: str, listen: bool) -> tuple[str | None, int | None]:
    if "@" in netloc:
        raise URLError(f"{shown(url)}: a gripper URL carries no user name (nothing before '@')")
    if netloc.startswith("["):
        end = netloc.find("]")
        if end < 0:
            raise URLError(f"{shown(url)}: unclosed '[' of an IPv6 address")
        raw_host, after = netloc[1:end], netloc[end + 1 :]
        host = _decoded(url, raw_host, "host").lower()
        try:
            ipaddress.IPv6Address(host.partition("%")[0])
        except ValueError:
            raise URLError(f"{shown(url)}: [{raw_host[:60]}] is not an IPv6 address") from None
        if after and not after.startswith(":"):
            raise URLError(f"{shown(url)}: {after[:40]!r} after the IPv6 address (expected :PORT)")
        port_text = after[1:] if after else ""
    else:
        if "[" in netloc or "]" in netloc:
            raise URLError(f"{shown(url)}: unbalanced brackets in {netloc[:60]!r}")
        raw_host, _, port_text = netloc.partition(":")
        if ":" in port_text:
            raise URLError(
                f"{shown(url)}: an IPv6 address is written in brackets, e.g. FAMILY+tcp://[::1]:1000"
            )
        host = _decoded(url, raw_host, "host").lower()
        _check_host_name(url, host)
    if not host and not listen:
        raise URLError(f"{shown(url)}: no host")
    port: int | None = None
    if port_text:
        if not (port_text.isascii() and port_text.isdigit()) or len(port_text) > 5 or int(port_text) > 65535:
            raise URLError(f"{shown(url)}: bad port {port_text[:20]!r} (1..65535)")
        port = int(port_text)
        if port == 0 and not listen:
            # Port 0 means "any port" to a socket; connecting there silently went to the profile's default.
            raise URLError(
                f"{shown(url)}: port 0 is not a port a gripper listens on (1..65535, or leave it out)"
            )
    return host or None, port


def _check_host_name(url: str, host: str) -> None:
    """Refuse a host name that no resolver could take (``a..b``: an empty label), here, as a URLError,
    instead of a UnicodeError from the IDNA codec when the socket connects."""
    if not host:
        return
    try:
        ipaddress.ip_address(host)
        return
    except ValueError:
        pass
    try:
        host.encode("idna")
    except UnicodeError as exc:
        raise URLError(f"{shown(url)}: {host[:80]!r} is not a valid host name ({exc})") from None


def _decoded(url: str, text: str, what: str) -> str:
    value = unquote(text)
    _no_control(url, value, what)
    return value


def _no_control(url: str, text: str, what: str) -> None:
    if _CONTROL.search(text):
        raise URLError(f"{shown(url)}: a control character in the {what}")


def _parse_serial(url: str, family: str, rest: str) -> ConnectionURL:
    # The port may be a pyserial URL with its own "://"; our parameters follow the last "?".
    port, _, query = rest.rpartition("?") if "?" in rest else (rest, "", "")
    port = _decoded(url, port, "serial port")
    if not port:
        raise URLError(f"{shown(url)}: no serial port (e.g. {family}+serial:///dev/ttyUSB0)")
    return ConnectionURL(url, family, "serial", serial_port=port, params=parse_query(url, query))


def _parse_sim(url: str, rest: str) -> ConnectionURL:
    if "#" in rest:
        raise URLError(f"{shown(url)}: a connection URL has no #fragment (write # in a value as %23)")
    base, _, query = rest.partition("?")
    if "[" in base or "]" in base:
        raise URLError(f"{shown(url)}: {base[:60]!r} is not a profile name")
    profile = _decoded(url, base, "profile").strip("/") or None
    return ConnectionURL(url, "sim", "", profile=profile, params=parse_query(url, query))


def _parse_zenoh(url: str, rest: str) -> ConnectionURL:
    name, _, query = rest.partition("?")
    served = _decoded(url, name, "served name").strip("/") or None
    return ConnectionURL(url, "zenoh", "zenoh", channel=served, params=parse_query(url, query))


def to_int(value: Any, name: str, url: str = "") -> int:
    """Integers in queries may be decimal or 0x-hex (CAN ids are written in hex)."""
    if isinstance(value, bool):
        raise URLError(f"{url or 'settings'}: {name} must be an integer, not {value!r}")
    if isinstance(value, int):
        return value
    try:
        return int(str(value), 0)
    except ValueError:
        raise URLError(f"{url or 'settings'}: {name} must be an integer, not {str(value)[:40]!r}") from None


def to_float(value: Any, name: str, url: str = "") -> float:
    """A finite number: no setting (timeout, time scale, a width) means anything as nan or inf, and a nan
    timeout would make every deadline comparison false, i.e. a wait without end."""
    return finite(value, name, device=url or "settings", error=URLError, text=True)


def to_bool(value: Any, name: str, url: str = "") -> bool:
    if isinstance(value, bool):
        return value
    text = str(value).lower()
    if text in ("1", "true", "yes", "on"):
        return True
    if text in ("0", "false", "no", "off"):
        return False
    raise URLError(f"{url or 'settings'}: {name} must be true or false, not {str(value)[:40]!r}")


# --- Zenoh endpoints (zenoh://NAME?connect=tcp/HOST:7447, grippers serve --listen) -------------------------


# Zenoh's endpoints whose address is HOST:PORT (the others, a Unix socket or a serial line, carry a path).
ZENOH_IP_PROTOCOLS = ("tcp", "udp", "tls", "quic", "ws")


def zenoh_endpoint(endpoint: str, what: str) -> tuple[str, str | None, int | None]:
    """A Zenoh endpoint (``tcp/127.0.0.1:7447``, ``tls/[::1]:7447#iface=lo``, ``unixsock-stream/path``) as
    (protocol, host, port); host and port are None for a protocol without an IP address. A URLError naming
    ``what`` (``--listen``, ``zenoh://…: connect``) for one that cannot be an endpoint, said before anything
    opens instead of Zenoh's error from deep inside its session."""
    proto, slash, rest = endpoint.partition("/")
    if not slash or not proto or not rest:
        raise URLError(f"{what} {endpoint!r}: an endpoint is PROTOCOL/ADDRESS, e.g. tcp/127.0.0.1:7447")
    if proto not in ZENOH_IP_PROTOCOLS:
        return proto, None, None
    address = rest.split("#", 1)[0].split("?", 1)[0]  # Zenoh's own metadata (#iface=) and config (?)
    try:
        host, port = parse_address(address, listen=True)
    except URLError:
        host, port = None, -1
    if host is None or port < 0:
        raise URLError(f"{what} {endpoint!r}: the address must be HOST:PORT with a port of 0-65535")
    return proto, host, port


def zenoh_port(endpoint: str) -> int | None:
    """The port of a Zenoh endpoint; None for one without (a Unix socket) or one that is no endpoint."""
    try:
        return zenoh_endpoint(endpoint, "endpoint")[2]
    except URLError:
        return None


def check_endpoints(endpoints: list[str], what: str) -> list[str]:
    """``endpoints`` as given, each checked by :func:`zenoh_endpoint`."""
    for endpoint in endpoints:
        zenoh_endpoint(endpoint, what)
    return endpoints


def zenoh_endpoints(text: str, what: str) -> list[str]:
    """A ``zenoh://`` URL's ``connect=`` value, endpoints joined by ``,``, as a checked list."""
    return check_endpoints([e for e in text.split(",") if e], what)


def served_url(name: str, params: Mapping[str, str]) -> str:
    """``zenoh://NAME?k=v``: the URL of a gripper served under ``name``, with a discovery URL's settings."""
    rest = "&".join(f"{k}={quote(v, safe='/:,.[]')}" for k, v in params.items())
    return f"zenoh://{name}?{rest}"
