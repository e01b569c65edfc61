"""``grippers doctor``: what this machine needs before a gripper can work, one line per check with ok, warn
or fail and the fix.

Checks are plain functions over what the operating system shows (``/sys/class/net``, ``/sys/module``,
device files, ``ip -details -json link``), each returning :class:`Check` rows, so each rule is tested on a
prepared directory. Nothing is sent to any device or network: the route to each family's factory address
(its backend's ``factory_address`` hook) is looked up with an unconnected UDP socket's ``connect``, which
sends no packet.
"""

from __future__ import annotations

import argparse
import importlib.util
import json
import os
import sys
from dataclasses import asdict, dataclass
from pathlib import Path
from typing import Any

from .output import DOCTOR_SCHEMA_ID, EXIT_FAILED, EXIT_OK, write_json

HELP = "check this machine: python-can, SocketCAN, vcan, serial ports and permissions, route, extras"
EXAMPLE = "grippers doctor\n         grippers doctor --json"

ARPHRD_CAN = "280"  # linux/if_arp.h: the link type of a SocketCAN interface in /sys/class/net/*/type
EXTRAS = {  # extra -> (the module it brings, what it is for)
    "yaml": ("yaml", "YAML profiles"),
    "plot": ("matplotlib", "grippers plot"),
    "test": ("msgpack", "python-can's udp_multicast bus, used by the tests"),
}


TROUBLESHOOTING = "docs/troubleshooting.md"
# Which section of the troubleshooting page explains a check that is not ok, by the check's first word.
SEE = {
    "python-can": "#installing",
    "pyserial": "#installing",
    "pydantic": "#installing",
    "can:": "#can-bus",
    "socketcan": "#can-bus",
    "vcan": "#can-bus",
    "serial": "#serial-ports",
    "route": "#network",
    "extra": "#installing",
}


@dataclass(frozen=True)
class Check:
    name: str
    status: str  # ok, warn, fail
    detail: str
    fix: str | None = None

    @property
    def see(self) -> str | None:
        """The troubleshooting section explaining a check that is not ok (issue 22 §4)."""
        if self.status == "ok":
            return None
        return TROUBLESHOOTING + SEE.get(self.name.split()[0], "")


def add_arguments(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("--json", action="store_true", help="print one JSON document (schema in docs/cli.md)")


# --- the checks ---------------------------------------------------------------------------------------------


def check_dependencies() -> list[Check]:
    out = []
    for module, what in (("can", "python-can"), ("serial", "pyserial"), ("pydantic", "pydantic")):
        if importlib.util.find_spec(module) is None:
            out.append(Check(what, "fail", "not installed", f"pip install {what}"))
            continue
        from importlib import metadata

        try:
            version = metadata.version(what)
        except metadata.PackageNotFoundError:
            version = "?"
        out.append(Check(what, "ok", f"version {version}"))
    return out


def check_can_interfaces() -> list[Check]:
    """The python-can interfaces the grippers use: importable, and usable where that can be tried locally."""
    import socket

    if importlib.util.find_spec("can") is None:
        return []
    import can

    out = []
    try:
        with can.Bus(interface="virtual", channel="grippers-doctor"):
            pass
        out.append(Check("can: virtual", "ok", "in-process bus (sim://, tests)"))
    except Exception as exc:
        out.append(Check("can: virtual", "fail", f"cannot open: {exc}", "pip install --upgrade python-can"))
    if not hasattr(socket, "AF_CAN"):
        out.append(Check("can: socketcan", "warn", "not available on this platform (Linux only)"))
    else:
        try:
            socket.socket(socket.AF_CAN, socket.SOCK_RAW, socket.CAN_RAW).close()
            out.append(Check("can: socketcan", "ok", "the kernel has CAN sockets"))
        except OSError as exc:
            out.append(
                Check(
                    "can: socketcan",
                    "warn",
                    f"no CAN sockets: {exc.strerror or exc} (a container without CAN support?)",
                    "use a host with the can and can_raw kernel modules (sudo modprobe can_raw)",
                )
            )
    if importlib.util.find_spec("msgpack") is None:
        out.append(Check("can: udp_multicast", "warn", "needs msgpack", "pip install msgpack"))
    else:
        out.append(Check("can: udp_multicast", "ok", "msgpack installed (a bus between processes)"))
    return out


def _ip_details() -> dict[str, dict[str, Any]]:
    import subprocess

    try:
        proc = subprocess.run(
            ["ip", "-details", "-json", "link", "show"], capture_output=True, text=True, timeout=5
        )
        return {link["ifname"]: link for link in json.loads(proc.stdout or "[]")}
    except (OSError, subprocess.SubprocessError, ValueError):
        return {}


def check_socketcan(
    sys_class_net: str = "/sys/class/net", details: dict[str, dict] | None = None
) -> list[Check]:
    """Every SocketCAN interface with its state and bit rate (from ``ip -details``)."""
    names = []
    try:
        entries = sorted(os.listdir(sys_class_net))
    except OSError:
        entries = []
    for name in entries:
        try:
            if Path(sys_class_net, name, "type").read_text().strip() == ARPHRD_CAN:
                names.append(name)
        except OSError:
            continue
    if not names:
        return [
            Check(
                "socketcan interfaces",
                "warn",
                "none (no CAN adapter, or its driver is not loaded)",
                "plug in the adapter; for tests: sudo scripts/setup-vcan.sh",
            )
        ]
    details = _ip_details() if details is None else details
    out = []
    for name in names:
        try:
            state = Path(sys_class_net, name, "operstate").read_text().strip().lower()
        except OSError:
            state = "unknown"
        info = (details.get(name) or {}).get("linkinfo", {})
        kind = info.get("info_kind", "can")
        data = info.get("info_data", {}) or {}
        bitrate = (data.get("bittiming") or {}).get("bitrate")
        can_state = data.get("state")  # ERROR-ACTIVE, ERROR-PASSIVE, BUS-OFF, STOPPED
        words = [kind, state]
        if can_state:
            words.append(can_state.lower())
        if bitrate:
            words.append(f"{bitrate} bit/s")
        detail = ", ".join(words)
        up = state in ("up", "unknown") and not (
            Path(sys_class_net, name, "flags").exists() and _flags_down(Path(sys_class_net, name, "flags"))
        )
        if not up:
            fix = f"sudo ip link set {name} up" + ("" if kind == "vcan" else " type can bitrate 1000000")
            out.append(Check(f"socketcan {name}", "fail", f"{detail}: down", fix))
        elif can_state and can_state.upper() == "BUS-OFF":
            fix = f"check the wiring, then: sudo ip link set {name} down; sudo ip link set {name} up"
            out.append(Check(f"socketcan {name}", "fail", f"{detail}: bus-off", fix))
        elif can_state and can_state.upper() == "ERROR-PASSIVE":
            fix = "check the bit rate and the 120 ohm terminators"
            out.append(Check(f"socketcan {name}", "warn", detail, fix))
        else:
            out.append(Check(f"socketcan {name}", "ok", detail))
    return out


def _flags_down(path: Path) -> bool:
    try:
        return not int(path.read_text().strip(), 16) & 0x1  # IFF_UP (linux/if.h)
    except (OSError, ValueError):
        return False


def check_vcan(sys_module: str = "/sys/module") -> list[Check]:
    if Path(sys_module, "vcan").exists():
        return [Check("vcan module", "ok", "loaded")]
    return [
        Check(
            "vcan module",
            "warn",
            "not loaded (only needed for virtual SocketCAN tests; containers often lack it)",
            "sudo modprobe vcan, or use can://udp_multicast/239.74.163.2 between processes",
        )
    ]


def check_serial_ports(ports: list[str] | None = None) -> list[Check]:
    """Serial ports, and whether this user may open them (the dialout group on most distributions)."""
    if ports is None:
        try:
            from serial.tools import list_ports

            ports = sorted(p.device for p in list_ports.comports())
        except ImportError:
            return []
    if not ports:
        fix = "plug in the gripper's USB-serial adapter (RS-232, RS-485 or UART)"
        return [Check("serial ports", "warn", "none found", fix)]
    out = []
    for port in ports:
        if os.access(port, os.R_OK | os.W_OK):
            out.append(Check(f"serial {port}", "ok", "can be opened"))
            continue
        group = _group_of(port)
        fix = f"sudo usermod -aG {group} $USER, then log in again" if group else f"sudo chmod a+rw {port}"
        out.append(Check(f"serial {port}", "fail", f"permission denied (group {group or '?'})", fix))
    return out


def _group_of(path: str) -> str | None:
    try:
        import grp

        return grp.getgrgid(os.stat(path).st_gid).gr_name
    except (ImportError, KeyError, OSError):
        return None


def factory_addresses() -> list[tuple[str, int, str]]:
    """(host, port, family) of every installed family's factory network address (``factory_address``
    hook, a ``tcp://HOST:PORT`` URL), once per host. A family that does not load is left out: the
    dependency checks above say why."""
    from grippers.backends import available_backends, find_backend
    from grippers.backends.command_hooks import commands_of
    from grippers.urls import parse_url

    out: dict[str, tuple[str, int, str]] = {}
    for family in available_backends():
        try:
            address = commands_of(find_backend(family)).factory_address
            if address is None:
                continue
            where = parse_url(address, bare_family="bare")
        except Exception:
            continue
        if where.host and where.host not in out:
            out[where.host] = (where.host, where.port or 0, family)
    return list(out.values())


def check_route(address: str, port: int = 0, family: str = "a gripper") -> list[Check]:
    """Which local address would talk to a family's factory address; connect() on UDP sends nothing."""
    import socket

    name = f"route to {address}"
    mine = address.rsplit(".", 1)[0] + ".100/24"  # an address of this computer on the gripper's /24 network
    try:
        with socket.socket(socket.AF_INET, socket.SOCK_DGRAM) as s:
            s.connect((address, port))
            local = s.getsockname()[0]
    except OSError as exc:
        return [
            Check(
                name,
                "warn",
                f"no route ({exc.strerror or exc}); needed for a {family} gripper on Ethernet at its "
                "factory address",
                f"sudo ip addr add {mine} dev eth0 (your Ethernet interface)",
            )
        ]
    if local.rsplit(".", 1)[0] == address.rsplit(".", 1)[0]:
        return [Check(name, "ok", f"direct, from {local}")]
    return [
        Check(
            name,
            "warn",
            f"only through a gateway (from {local}); a {family} gripper at its factory address is on a "
            "direct link",
            f"sudo ip addr add {mine} dev eth0 (the interface the gripper is plugged into)",
        )
    ]


def check_extras() -> list[Check]:
    out = []
    for extra, (module, what) in EXTRAS.items():
        if importlib.util.find_spec(module) is not None:
            out.append(Check(f"extra {extra}", "ok", f"{module} installed ({what})"))
        else:
            install = f"pip install 'grippers[{extra}]'"
            out.append(Check(f"extra {extra}", "warn", f"{module} not installed ({what})", install))
    return out


def check_profiles() -> list[Check]:
    """Built-in profiles replaced by a file, missing plugin profile folders (cli/profile_notes.py)."""
    from .profile_notes import profile_notes

    notes = profile_notes()
    if not notes:
        return [Check("profiles", "ok", "no built-in profile replaced, every plugin folder found")]
    return [Check("profiles", "warn", note, "grippers profiles path") for note in notes]


def collect() -> list[Check]:
    return [
        *check_dependencies(),
        *check_profiles(),
        *check_can_interfaces(),
        *check_socketcan(),
        *check_vcan(),
        *check_serial_ports(),
        *(c for host, port, family in factory_addresses() for c in check_route(host, port, family)),
        *check_extras(),
    ]


def run(args: argparse.Namespace) -> int:
    checks = collect()
    failed = any(c.status == "fail" for c in checks)
    if args.json:
        rows = [{**asdict(c), "see": c.see} for c in checks]
        write_json({"schema": DOCTOR_SCHEMA_ID, "ok": not failed, "checks": rows})
    else:
        width = max(len(c.name) for c in checks)
        for c in checks:  # one line each: status, what, what was found, and the fix when there is one
            fix = f"; fix: {c.fix}" if c.fix and c.status != "ok" else ""
            see = f" (see {c.see})" if c.see else ""
            print(f"{c.status.upper():<4}  {c.name:<{width}}  {c.detail}{fix}{see}")
        counts = {s: sum(c.status == s for c in checks) for s in ("ok", "warn", "fail")}
        print(f"\n{counts['ok']} ok, {counts['warn']} warning(s), {counts['fail']} failure(s)")
    sys.stdout.flush()
    return EXIT_FAILED if failed else EXIT_OK
