"""The WSG family's command-line hooks: ``grippers sim wsg`` (a WSG simulator on TCP, UDP, a pseudo-terminal
or a CAN bus, or the replay of a capture). The backend offers this module as its ``cli_sim``."""

from __future__ import annotations

import argparse
from typing import Any

from ..cli.sim_common import (
    add_sim_arguments,
    serve_forever,
    serve_replay,
    settings_for,
    start_server,
    warn_private_bus,
)

# The WSG's own port (docs/protocols.md §1): scripts written for the device work unchanged against the
# simulator. A user without root gets a free port instead, and is told (sim_common.start_server).
DEFAULT_LISTEN = "tcp://127.0.0.1:1000"

NAMES = ("wsg",)  # `grippers sim wsg`
HELP = "simulate a WSG gripper (binary protocol) on tcp://, udp://, pty or can://"
EXAMPLE = (
    "grippers sim wsg --listen tcp://127.0.0.1:1000\n"
    "         grippers sim wsg --listen pty --firmware 2.2.0 --part-width 40\n"
    "         grippers sim wsg --listen 'can://udp_multicast/239.74.163.2?send_id=0x7E8&recv_id=0x7E9'\n"
    "         grippers sim wsg --replay session.hex --listen tcp://127.0.0.1:1000   (monitor --write)"
)


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
    from grippers.drivers.wsg.sim.replay import WsgReplayServer, wsg_script
    from grippers.urls import parse_url

    from ..cli.output import UsageError

    script = wsg_script(blob, args.replay)
    listen = args.listen or DEFAULT_LISTEN
    if listen.partition("://")[0] != "tcp":
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
            lambda where: backend.simulator(profile, settings, listen=where), args.listen, DEFAULT_LISTEN
        )
    except ValueError as exc:  # a malformed --listen or --firmware: the command line's fault
        raise UsageError(str(exc)) from None
    settings.finish()
    what = f"simulated {profile.model} (firmware {server.model.firmware})"
    return serve_forever(server, what, as_json=args.json)
