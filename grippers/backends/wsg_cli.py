"""The WSG family's command hooks (:class:`WsgCommands`, the backend's ``commands``): ``grippers sim wsg`` (a
WSG simulator on TCP, UDP, a pseudo-terminal or a CAN bus, or the replay of a capture), the probe's
candidates, raw check and factory address, the monitor's dissector, the device settings and the self-test's
lines (the last two in wsg_settings.py).

Transport defaults (ports, serial speed) are the profile model's (``WsgTransport``), read from there."""

from __future__ import annotations

import argparse
from collections.abc import Callable
from typing import Any

from ..cli.sim_common import (
    add_sim_arguments,
    serve_forever,
    serve_replay,
    settings_for,
    start_server,
    warn_private_bus,
)
from . import wsg_settings
from .command_hooks import CommandHooks, Dissector, ProbeCandidate, RawProbe, bus_query


def default_listen() -> str:
    """The WSG's own port (the profile model's, docs/protocols.md §1): scripts written for the device work
    unchanged against the simulator. A user without root gets a free port instead, and is told
    (sim_common.start_server)."""
    return f"tcp://127.0.0.1:{_transport().tcp_port}"


def add_arguments(parser: argparse.ArgumentParser) -> None:
    add_sim_arguments(
        parser,
        "wsg50",
        "tcp://HOST:PORT, udp://HOST:PORT, pty or can://INTERFACE/CHANNEL[?send_id=ID&recv_id=ID] (default "
        "tcp://127.0.0.1:1000, the device's port, or a free port for a user without root; port 0 picks a "
        "free port; binds to loopback unless a host is named)",
    )
    parser.add_argument(
        "--firmware",
        metavar="X.Y.Z",
        help="firmware to simulate, e.g. 4.0.1 or 2.2.0 (2.x lacks 46h and the finger commands; default: "
        "the profile's)",
    )


def _replay(args: argparse.Namespace, blob: bytes) -> tuple[Any, Any]:
    from grippers.drivers.urls import scheme_of
    from grippers.drivers.wsg.sim.replay import WsgReplayServer, wsg_script
    from grippers.urls import parse_url

    from ..cli.output import UsageError

    script = wsg_script(blob, args.replay)
    listen = args.listen or default_listen()
    if scheme_of(listen) != "tcp":
        raise UsageError(f"--replay serves a WSG on tcp://HOST:PORT, not {listen!r}")
    where = parse_url(listen, bare_family="wsg", listen=True)  # the one grammar: drivers/urls.py
    host, port = where.host, where.port
    if not host or port is None:
        raise UsageError(f"--replay serves a WSG on tcp://HOST:PORT, not {listen!r}")
    server = start_server(lambda _: WsgReplayServer(script, host, port, args.time_scale), listen, listen)
    return server, script


def run(args: argparse.Namespace, backend: Any) -> int:
    from grippers.profiles import load_profile

    if args.replay:
        return serve_replay(args, lambda blob: _replay(args, blob))

    from ..cli.output import UsageError

    profile = load_profile(args.profile)
    if profile.family != backend.family:
        raise UsageError(f"profile {profile.name} is a {profile.family} profile, not a WSG one")
    warn_private_bus(args.listen or "")
    settings = settings_for(profile, args, firmware=args.firmware)
    try:
        server = start_server(
            lambda where: backend.simulator(profile, settings, listen=where), args.listen, default_listen()
        )
    except ValueError as exc:  # a malformed --listen or --firmware: the command line's fault
        raise UsageError(str(exc)) from None
    settings.finish()
    what = f"simulated {profile.model} (firmware {server.model.firmware})"
    return serve_forever(server, what, as_json=args.json)


# --- grippers probe ----------------------------------------------------------------------------------------
# The set-up default address (docs/protocols.md §1 "Transport defaults"): the machine scan and doctor's route.
FACTORY_HOST = "192.168.1.20"


def _transport() -> Any:
    """The profile model's transport defaults, the one home of the ports and the serial speed."""
    from .wsg_profile import WsgTransport

    return WsgTransport()


# The WSG over CAN: commands on a base id, replies on base + 1, base 0x000 (docs/protocols.md §1, one public
# driver); the probe adds the ids of every WSG profile on the search path.
CAN_IDS: tuple[tuple[int, int], ...] = ((0x000, 0x001),)


def can_ids(given: list[int] | None) -> tuple[tuple[int, int], ...]:
    """``--can-id`` as id pairs, or those of every WSG profile on the search path."""
    if given:
        return tuple((i, i + 1) for i in dict.fromkeys(given))
    from grippers.profiles import list_profiles

    from .wsg_profile import WsgProfile

    ids = {
        (p.transport.can_send_id, p.transport.can_recv_id)
        for p in list_profiles()
        if isinstance(p, WsgProfile)
    }
    return tuple(sorted(ids)) or CAN_IDS


class WsgSim:
    """``grippers sim wsg``: its own options (``--firmware``, ``--replay``) and run."""

    add_arguments = staticmethod(add_arguments)
    run = staticmethod(run)


class WsgCommands(CommandHooks):
    """What the commands ask of the WSG family (grippers.backends.CommandHooks)."""

    sim_names = ("wsg",)
    sim_help = "simulate a WSG gripper (binary protocol) on tcp://, udp://, pty or can://"
    sim_example = (
        "grippers sim wsg --listen tcp://127.0.0.1:1000\n"
        "         grippers sim wsg --listen pty --firmware 2.2.0 --part-width 40\n"
        "         grippers sim wsg --listen 'can://udp_multicast/239.74.163.2?send_id=0x7E8&recv_id=0x7E9'\n"
        "         grippers sim wsg --replay session.hex --listen tcp://127.0.0.1:1000   (monitor --write)"
    )
    settings_options = wsg_settings.OPTIONS
    reports_stroke = True  # 53h: selftest compares it with the profile

    def __init__(self) -> None:
        self.factory_address = f"tcp://{FACTORY_HOST}:{_transport().tcp_port}"

    def bare_forms(self) -> dict[str, tuple[int, str]]:
        """A bare transport's URL as a WSG's (the "did you mean" of a mistyped target), ranked."""
        return {
            "tcp": (10, "wsg+tcp://{rest}"),
            "udp": (10, "wsg+udp://{rest}"),
            "serial": (10, "wsg+serial://{rest}"),
            "can": (20, "wsg+can://{rest}"),
        }

    def probe_candidates(self, transport: str, where: Any, options: dict[str, Any]) -> list[ProbeCandidate]:
        from grippers.urls import format_host

        t = _transport()
        if transport in ("tcp", "udp"):
            port = where.port or (t.tcp_port if transport == "tcp" else t.udp_port)
            return [ProbeCandidate(f"wsg+{transport}://{format_host(where.host, port)}", order=10)]
        if transport == "serial":
            return [ProbeCandidate(f"wsg+serial://{where.serial_port}?baudrate={t.baudrate}", order=10)]
        if transport != "can":
            return []
        out = []
        for send_id, recv_id in can_ids(options.get("can_ids")):
            url = (
                f"wsg+can://{where.interface}/{where.channel}?send_id=0x{send_id:03X}&recv_id=0x{recv_id:03X}"
            )
            # A STEPFOC node answering on the ids a WSG packet would use must not receive one (an id with
            # command 0 is that node's E-stop): those WSG candidates wait for the node probe.
            nodes = tuple({i >> 7 for i in (send_id, recv_id)})
            out.append(ProbeCandidate(url + bus_query(options), order=20, unless_nodes=nodes))
        return out

    def raw_probe(self, transport: str) -> RawProbe:
        from grippers.drivers.wsg import probe as wsg_probe

        return RawProbe(
            wsg_probe.identify_request(),
            goodbye=wsg_probe.goodbye(transport),  # a WSG on TCP must not be left in FAST STOP by this check
            is_answer=wsg_probe.holds_a_packet,
            port=_transport().tcp_port if transport == "tcp" else _transport().udp_port,
        )

    def dissector(self) -> Dissector:
        """``grippers monitor``: WSG packets from bytes (captures, the TCP proxy) or CAN frames (commands on
        ``--can-id``, replies on the next id)."""
        from grippers.drivers.wsg.dissect import PROTOCOL, WsgCanDissector, WsgStream
        from grippers.drivers.wsg.protocol import PREAMBLE

        return Dissector(
            PROTOCOL,
            stream=WsgStream,
            can=lambda o: WsgCanDissector(o.get("can_id", 0x000), bool(o.get("only"))),
            tcp_port=_transport().tcp_port,
            bytes_default=True,
            finds=lambda data: PREAMBLE in data,
        )

    def read_settings(self, gripper: Any) -> dict[str, Any]:
        return wsg_settings.read_values(gripper.driver)

    def check_settings(self, gripper: Any, args: argparse.Namespace) -> None:
        wsg_settings.check_values(gripper, args)

    def change_settings(self, gripper: Any, args: argparse.Namespace, changed: list[str]) -> None:
        wsg_settings.change_values(gripper, args, changed)

    def selftest_checks(self, gripper: Any, add: Callable[..., None]) -> None:
        wsg_settings.selftest_checks(gripper, add)

    def sim_command(self) -> WsgSim:
        return WsgSim()
