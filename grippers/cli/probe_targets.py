"""What ``grippers probe`` tries for a target: the family URLs a bare transport can carry.

No I/O except the machine scan in :func:`machine_targets`, so the expansion rules are tested without
devices. A bare transport names only where to look; every installed family's backend says what it would try
there (its ``probe_candidates`` hook, issue 28 §2: a WSG's ports, a STEPFOC's nodes, a Robotiq's Modbus
slave), and all of them are tried.
"""

from __future__ import annotations

import ipaddress
import os
from dataclasses import dataclass, field
from typing import Any

from grippers.drivers.urls import BUS_OPTIONS, bus_options, is_url, refuse_unknown, scheme_of
from grippers.errors import URLError
from grippers.urls import ConnectionURL, parse_url, to_int

from .output import UsageError

BARE_SCHEMES = ("tcp", "udp", "serial", "can")


@dataclass(frozen=True)
class Candidate:
    """One URL to open, where it is, and the group it shares a resource with (tried one after another)."""

    url: str
    location: dict[str, Any]
    group: str
    # When set, the candidate is only tried if no device answered at these nodes on the same bus (a WSG packet
    # on CAN id 0x000/0x001 would be an E-stop frame for STEPFOC node 0, docs/protocols.md §1, §2).
    unless_nodes: tuple[int, ...] = ()
    protocol: str | None = None  # the candidate's ProbeCandidate.protocol (probe_identity.py)


@dataclass
class Plan:
    candidates: list[Candidate] = field(default_factory=list)
    skipped: list[dict[str, str]] = field(default_factory=list)
    sim_all: bool = False


def empty_location() -> dict[str, Any]:
    return {
        "transport": None,
        "host": None,
        "port": None,
        "serial_port": None,
        "interface": None,
        "channel": None,
        "node": None,
        "profile": None,
    }


class TargetError(UsageError, URLError):
    """A target the URL grammar refuses: the grammar's URLError, and a usage error of the command (exit 2)."""


def _parse(text: str, bare: bool = False) -> ConnectionURL:
    """The one grammar (``drivers/urls.py``); a bare ``tcp://`` is read as a transport, for its checks."""
    try:
        return parse_url(text, bare_family="bare" if bare else None)
    except URLError as exc:
        raise TargetError(exc.message) from None


def location_of(url: str) -> dict[str, Any]:
    """Where a family URL points, as the ``location`` object of the probe schema."""
    loc = empty_location()
    u = _parse(url)
    loc["transport"] = u.transport or "sim"
    loc["host"], loc["port"] = u.host, u.port
    loc["serial_port"], loc["profile"] = u.serial_port, u.profile
    if u.transport == "can":
        loc["interface"], loc["channel"] = u.interface, u.channel
        if "node" in u.params:
            try:
                loc["node"] = to_int(u.params["node"], "node", url)
            except URLError:
                loc["node"] = None  # opening it says why
    return loc


def expand(target: str, bitrate: int | None = None, options: dict[str, Any] | None = None) -> Plan:
    """The candidates for one target given on the command line; raises UsageError for a malformed one
    (a :class:`TargetError`, also the grammar's URLError, when the URL grammar refuses it).

    ``options``: what the families' ``probe_candidates`` hooks may read (``can_ids``: ``--can-id``)."""
    text = target.strip()
    plan = Plan()
    if text.startswith("/") or (len(text) > 3 and text[:3].upper() == "COM" and text[3:].isdigit()):
        text = f"serial://{text}"  # a bare device path is a serial port
    if not is_url(text):
        from .suggest import hint

        fix = hint(text)
        raise UsageError(
            f"{target!r} is not a URL (expected e.g. tcp://HOST, can://IF/CH, serial:///dev/ttyX)"
            + (f" ({fix})" if fix else "")
        )
    scheme = scheme_of(text)
    if scheme == "sim":
        u = _parse(text)
        if u.profile:
            plan.candidates.append(Candidate(text, location_of(text), group=text))
        else:
            plan.sim_all = True
        return plan
    if _is_family_scheme(scheme):
        _parse(text)
        plan.candidates.append(Candidate(text, location_of(text), group=_group_of(text)))
        return plan
    if scheme not in BARE_SCHEMES:
        from .suggest import hint

        known = ", ".join((*BARE_SCHEMES, "FAMILY+TRANSPORT (e.g. FAMILY+tcp)", "sim"))
        fix = hint(text)
        raise UsageError(
            f"{target!r}: unknown scheme {scheme!r} (known: {known})" + (f"; {fix}" if fix else "")
        )
    u = _parse(text, bare=True)
    given: dict[str, Any] = {"bitrate": bitrate, **(options or {})}
    if scheme == "can":
        # The bus options the URL carries (?port= of a udp_multicast bus, ?bitrate=) go to every candidate
        # (grippers.backends.bus_query): dropped, the probe searched python-can's default port.
        try:
            refuse_unknown(text, u.params, BUS_OPTIONS)
            bus = bus_options(u)
        except URLError as exc:
            raise TargetError(exc.message) from None
        if bitrate:
            bus["bitrate"] = bitrate  # -b wins over the URL, as flags do everywhere
        given["bus"] = bus
    from grippers.backends.command_hooks import commands_of

    offered = []
    for backend in _backends():
        offered += commands_of(backend).probe_candidates(scheme, u, given)
    for c in sorted(offered, key=lambda c: c.order):  # stable: a family's own order within one rank
        # Candidates on one serial port share it, tried one after another; the rest each have their own.
        group = f"serial:{u.serial_port}" if scheme == "serial" else c.url
        where = location_of(c.url)
        plan.candidates.append(
            Candidate(c.url, where, group, unless_nodes=c.unless_nodes, protocol=c.protocol)
        )
    return plan


def _backends() -> list[Any]:
    """Every installed family's backend that loads (a missing optional dependency leaves one out)."""
    from grippers.backends import available_backends, find_backend

    out = []
    for family in available_backends():
        try:
            backend = find_backend(family)
        except Exception:
            continue
        if backend is not None:
            out.append(backend)
    return out


def _is_family_scheme(scheme: str) -> bool:
    """``wsg+tcp``, ``acme+tcp``, ``robotiq+urcap``: a family built in or installed through the
    ``grippers.backends`` entry points (docs/backends.md), on a transport or a scheme of its own."""
    from grippers.urls import family_scheme

    return family_scheme(scheme)


def _group_of(url: str) -> str:
    loc = location_of(url)
    if loc["serial_port"]:
        return f"serial:{loc['serial_port']}"
    return url


def is_loopback(host: str | None) -> bool:
    if host is None:
        return False
    if host == "localhost":
        return True
    try:
        return ipaddress.ip_address(host).is_loopback
    except ValueError:
        return False


def socketcan_interfaces(sys_class_net: str = "/sys/class/net") -> list[str]:
    """SocketCAN interfaces on this machine (ARPHRD_CAN = 280 in /sys/class/net/*/type, linux/if_arp.h)."""
    found = []
    try:
        names = sorted(os.listdir(sys_class_net))
    except OSError:
        return []
    for name in names:
        try:
            with open(os.path.join(sys_class_net, name, "type")) as fh:
                if fh.read().strip() == "280":
                    found.append(name)
        except OSError:
            continue
    return found


def serial_ports() -> list[str]:
    try:
        from serial.tools import list_ports
    except ImportError:  # pragma: no cover - pyserial is a dependency
        return []
    return sorted(p.device for p in list_ports.comports())


def machine_targets(network: bool, bitrate: int | None = None, options: dict[str, Any] | None = None) -> Plan:
    """What ``grippers probe`` with no URL looks at: serial ports, SocketCAN interfaces and the families'
    factory addresses (their ``factory_address`` hook: a TCP connection attempt each; ``--no-network`` leaves
    them out)."""
    from grippers.backends.command_hooks import commands_of

    plan = Plan()
    for port in serial_ports():
        plan.candidates += expand(f"serial://{port}", bitrate, options).candidates
    for name in socketcan_interfaces():
        plan.candidates += expand(f"can://socketcan/{name}", bitrate, options).candidates
    for backend in _backends():
        address = commands_of(backend).factory_address
        if address is None:
            continue
        if network:
            plan.candidates += [
                c for c in expand(address).candidates if c.url.startswith(backend.family + "+")
            ]
        else:
            plan.skipped.append(
                {"target": address, "reason": "network addresses are left out with --no-network"}
            )
    return plan
