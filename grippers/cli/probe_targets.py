"""What ``grippers probe`` tries for a target: the family URLs a bare transport can carry.

Pure string work (no I/O except the machine scan in :func:`machine_targets`), so the expansion rules are
tested without devices. A bare transport names only where to look; every protocol that can run there is
tried: WSG on TCP/UDP; WSG binary and STEPFOC UART on a serial port; STEPFOC nodes 0-15 and the WSG's CAN
ids on a CAN bus.
"""

from __future__ import annotations

import ipaddress
import os
from dataclasses import dataclass, field
from typing import Any

from grippers.drivers.urls import BUS_OPTIONS, bus_options, refuse_unknown
from grippers.errors import URLError
from grippers.urls import ConnectionURL, format_host, parse_url, to_int

from .output import UsageError

# Defaults not in the manuals; docs/protocols.md §1 "Transport defaults" and §2.
WSG_DEFAULT_HOST = "192.168.1.20"
WSG_TCP_PORT = 1000
WSG_UDP_PORT = 1500
WSG_SERIAL_BAUD = 115200
STEPFOC_UART_BAUD = 256000
STEPFOC_NODES = range(16)  # 4-bit node id (MSG manual, "Bits 10 - 7 of CAN ID")
# The WSG over CAN: commands on a base id, replies on base + 1, base 0x000 (docs/protocols.md §1, one public
# driver); the probe adds the ids of every WSG profile on the search path.
WSG_CAN_IDS: tuple[tuple[int, int], ...] = ((0x000, 0x001),)

BARE_SCHEMES = ("tcp", "udp", "serial", "can")
FAMILY_SCHEMES = ("wsg+tcp", "wsg+udp", "wsg+serial", "wsg+can", "stepfoc+can", "stepfoc+serial")


@dataclass(frozen=True)
class Candidate:
    """One URL to open, where it is, and the group it shares a resource with (tried one after another)."""

    url: str
    location: dict[str, Any]
    group: str
    # When set, the candidate is only tried if no STEPFOC device answered at these nodes on the same bus: a
    # WSG packet on CAN id 0x000/0x001 would be an E-stop frame for STEPFOC node 0 (docs/protocols.md §1, §2).
    unless_nodes: tuple[int, ...] = ()


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
    """The one grammar (``drivers/urls.py``); a bare ``tcp://`` is read as a WSG's, for its checks."""
    try:
        return parse_url(text, bare_family="wsg" if bare else None)
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


def expand(
    target: str, bitrate: int | None = None, wsg_can_ids: tuple[tuple[int, int], ...] = WSG_CAN_IDS
) -> Plan:
    """The candidates for one target given on the command line; raises UsageError for a malformed one
    (a :class:`TargetError`, also the grammar's URLError, when the URL grammar refuses it)."""
    text = target.strip()
    plan = Plan()
    if text.startswith("/") or (len(text) > 3 and text[:3].upper() == "COM" and text[3:].isdigit()):
        text = f"serial://{text}"  # a bare device path is a serial port
    if "://" not in text:
        from .suggest import hint

        fix = hint(text)
        raise UsageError(
            f"{target!r} is not a URL (expected e.g. tcp://HOST, can://IF/CH, serial:///dev/ttyX)"
            + (f" ({fix})" if fix else "")
        )
    raw_scheme = text.partition("://")[0]
    scheme = raw_scheme.lower()
    if scheme == "sim":
        u = _parse(text)
        if u.profile:
            plan.candidates.append(Candidate(text, location_of(text), group=text))
        else:
            plan.sim_all = True
        return plan
    if scheme in FAMILY_SCHEMES or _is_plugin_scheme(scheme):
        _parse(text)
        plan.candidates.append(Candidate(text, location_of(text), group=_group_of(text)))
        return plan
    if scheme not in BARE_SCHEMES:
        from .suggest import hint

        known = ", ".join(BARE_SCHEMES + FAMILY_SCHEMES + ("sim", "FAMILY+TRANSPORT of a plugin"))
        fix = hint(text)
        raise UsageError(
            f"{target!r}: unknown scheme {raw_scheme!r} (known: {known})" + (f"; {fix}" if fix else "")
        )
    u = _parse(text, bare=True)
    if scheme in ("tcp", "udp"):
        assert u.host is not None  # the grammar refuses a tcp/udp URL without a host
        port = u.port or (WSG_TCP_PORT if scheme == "tcp" else WSG_UDP_PORT)
        url = f"wsg+{scheme}://{format_host(u.host, port)}"
        plan.candidates.append(Candidate(url, location_of(url), group=url))
    elif scheme == "serial":
        path = u.serial_port
        group = f"serial:{path}"
        for url in (
            f"wsg+serial://{path}?baudrate={WSG_SERIAL_BAUD}",
            f"stepfoc+serial://{path}?baudrate={STEPFOC_UART_BAUD}",
        ):
            plan.candidates.append(Candidate(url, location_of(url), group=group))
    else:  # can
        interface, channel = u.interface, u.channel
        # The bus options the URL carries (?port= of a udp_multicast bus, ?bitrate=) go to every candidate:
        # dropped, the probe searched python-can's default port and found another process's nodes.
        try:
            refuse_unknown(text, u.params, BUS_OPTIONS)
            options = bus_options(u)
        except URLError as exc:
            raise TargetError(exc.message) from None
        if bitrate:
            options["bitrate"] = bitrate  # -b wins over the URL, as flags do everywhere
        extra = "".join(f"&{k}={v}" for k, v in options.items())
        for node in STEPFOC_NODES:
            url = f"stepfoc+can://{interface}/{channel}?node={node}{extra}"
            # Each node gets its own bus connection, so the nodes are asked in parallel.
            plan.candidates.append(Candidate(url, location_of(url), group=url))
        for send_id, recv_id in wsg_can_ids:
            url = f"wsg+can://{interface}/{channel}?send_id=0x{send_id:03X}&recv_id=0x{recv_id:03X}{extra}"
            # A STEPFOC node answering on the ids a WSG packet would use must not receive one (an id with
            # command 0 is that node's E-stop): those WSG candidates wait for the node probe.
            nodes = tuple({i >> 7 for i in (send_id, recv_id)})
            plan.candidates.append(Candidate(url, location_of(url), group=url, unless_nodes=nodes))
    return plan


def _is_plugin_scheme(scheme: str) -> bool:
    """``acme+tcp``: a family installed through the ``grippers.backends`` entry points (docs/backends.md)."""
    family, plus, transport = scheme.partition("+")
    if not plus or transport not in BARE_SCHEMES:
        return False
    from grippers.backends import available_backends

    return family in available_backends()


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


def machine_targets(
    network: bool, bitrate: int | None = None, wsg_can_ids: tuple[tuple[int, int], ...] = WSG_CAN_IDS
) -> Plan:
    """What ``grippers probe`` with no URL looks at: serial ports, SocketCAN interfaces and the WSG's factory
    address (a TCP connection attempt to 192.168.1.20:1000; ``--no-network`` leaves it out)."""
    plan = Plan()
    for port in serial_ports():
        plan.candidates += expand(f"serial://{port}").candidates
    for name in socketcan_interfaces():
        plan.candidates += expand(f"can://socketcan/{name}", bitrate, wsg_can_ids).candidates
    wsg = f"tcp://{WSG_DEFAULT_HOST}:{WSG_TCP_PORT}"
    if network:
        plan.candidates += expand(wsg).candidates
    else:
        plan.skipped.append({"target": wsg, "reason": "network addresses are left out with --no-network"})
    return plan
