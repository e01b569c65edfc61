"""``grippers sim msg``: MSG grippers on STEPFOC drivers, as CAN nodes or on a UART pseudo-terminal."""

from __future__ import annotations

import argparse

from .sim_common import add_sim_arguments, serve_forever, settings_for

HELP = "simulate MSG grippers (STEPFOC) as CAN nodes (can://IF/CH?node=N) or a UART device (pty)"
EXAMPLE = (
    "grippers sim msg --listen 'can://udp_multicast/239.74.163.2?node=0'\n"
    "         grippers sim msg --listen 'can://socketcan/vcan0?node=0,1,2'\n"
    "         grippers sim msg --listen pty --part-width 40"
)


def add_arguments(parser: argparse.ArgumentParser) -> None:
    add_sim_arguments(
        parser,
        "msg-150",
        "can://INTERFACE/CHANNEL?node=N (several nodes: node=0,1,2; another process reaches it over "
        "socketcan or udp_multicast) or pty (the UART protocol on a pseudo-terminal; the default)",
    )


def run(args: argparse.Namespace) -> int:
    from grippers.backends import get_backend
    from grippers.profiles import load_profile

    from .output import UsageError

    profile = load_profile(args.profile)
    if profile.family != "stepfoc":
        raise UsageError(f"profile {profile.name} is a {profile.family} profile, not an MSG one")
    backend = get_backend("stepfoc")
    listen = args.listen or "pty"
    nodes = [0]
    if listen.startswith("can://"):
        base, _, query = listen.partition("?")
        from urllib.parse import parse_qsl

        params = dict(parse_qsl(query))
        try:
            nodes = [int(n, 0) for n in params.pop("node", "0").split(",")]
        except ValueError:
            raise UsageError(f"--listen {listen}: node must be a number or a comma-separated list") from None
        if params:
            raise UsageError(f"--listen {listen}: unknown parameter(s) {', '.join(params)}")
        listen = base
    settings = settings_for(profile, args)
    part = settings.float("part_width_mm", profile.simulator.part_width_mm)
    models = [backend.sim_model(profile, node, part) for node in nodes]
    try:
        server = backend.serve(models, listen, settings)
    except ValueError as exc:  # a malformed --listen or --firmware: the command line's fault
        raise UsageError(str(exc)) from None
    settings.finish()
    what = f"simulated {profile.model}" + (f" (node {', '.join(map(str, nodes))})" if listen != "pty" else "")
    urls = getattr(server, "urls", None)  # the CAN server names every node it serves
    urls = list(urls() if callable(urls) else urls or [server.url])
    return serve_forever(server, what, urls)
