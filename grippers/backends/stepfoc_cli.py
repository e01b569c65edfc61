"""The STEPFOC family's command hooks (:class:`StepfocCommands`, the backend's ``commands``): ``grippers sim
msg`` (MSG grippers on STEPFOC drivers, as CAN nodes or on a UART pseudo-terminal, or the replay of a candump
log), the probe's candidates and raw check, the monitor's dissector, the device settings and the self-test's
lines (the last two in stepfoc_settings.py).

The UART's speed and the node range are the profile model's (``StepfocTransport``, ``MAX_NODE``)."""

from __future__ import annotations

import argparse
from collections.abc import Callable
from typing import Any

from ..cli.sim_common import add_sim_arguments, serve_forever, serve_replay, settings_for, warn_private_bus
from . import stepfoc_settings
from .command_hooks import CommandHooks, Dissector, ProbeCandidate, RawProbe, bus_query

BUS_PARAMETERS = ("port", "bitrate")


def add_arguments(parser: argparse.ArgumentParser) -> None:
    add_sim_arguments(
        parser,
        "msg-150",
        "can://INTERFACE/CHANNEL?node=N (several nodes: node=0,1,2; another process reaches it over "
        "socketcan or udp_multicast) or pty (the UART protocol on a pseudo-terminal; the default)",
    )


def _replay(args: argparse.Namespace, blob: bytes) -> tuple[Any, Any]:
    from grippers.drivers.stepfoc.sim.replay import StepfocReplayServer, stepfoc_script
    from grippers.drivers.urls import scheme_of
    from grippers.urls import parse_url, to_int

    from ..cli.output import UsageError

    script = stepfoc_script(blob, args.replay)
    listen = args.listen or ""
    if scheme_of(listen) != "can":
        raise UsageError("--replay serves STEPFOC nodes on a CAN bus: --listen can://INTERFACE/CHANNEL")
    where = parse_url(listen, bare_family="stepfoc")
    interface, channel = where.interface or "", where.channel or ""
    bus = {k: to_int(v, k, listen) for k, v in where.params.items() if k in BUS_PARAMETERS}
    if interface in ("virtual", "udp_multicast"):
        bus.pop("bitrate", None)
    warn_private_bus(listen)
    return StepfocReplayServer(script, interface, channel, args.time_scale, **bus), script


def run(args: argparse.Namespace, backend: Any) -> int:
    from grippers.profiles import load_profile

    from .stepfoc_profile import MsgProfile

    if args.replay:
        return serve_replay(args, lambda blob: _replay(args, blob))

    from ..cli.output import UsageError

    profile = load_profile(args.profile)
    if not isinstance(profile, MsgProfile):
        raise UsageError(f"profile {profile.name} is a {profile.family} profile, not an MSG one")
    listen = args.listen or "pty"
    nodes = [0]
    bus: dict[str, str] = {}
    from grippers.drivers.urls import append_params, scheme_of, with_query

    if scheme_of(listen) == "can":
        from grippers.urls import parse_url

        params = dict(parse_url(listen, bare_family="stepfoc").params)  # the one grammar: drivers/urls.py
        try:
            nodes = [int(n, 0) for n in params.pop("node", "0").split(",")]
        except ValueError:
            raise UsageError(f"--listen {listen}: node must be a number or a comma-separated list") from None
        # The bus options a client URL takes too: udp_multicast's port (a private port isolates a bus) and
        # the bit rate; the simulator opens its bus with them.
        unknown = [k for k in params if k not in BUS_PARAMETERS]
        if unknown:
            raise UsageError(
                f"--listen {listen}: unknown parameter(s) {', '.join(unknown)} "
                f"(known: node, {', '.join(BUS_PARAMETERS)})"
            )
        for key in params:
            try:
                int(params[key])
            except ValueError:
                raise UsageError(f"--listen {listen}: {key} must be a number") from None
        bus = params
        listen = with_query(listen, bus)
    warn_private_bus(listen)
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
    if bus:  # a client needs the same port to reach the bus
        urls = [append_params(u, bus) for u in urls]
    return serve_forever(server, what, urls, as_json=args.json)


class StepfocSim:
    """``grippers sim msg``: several CAN nodes on one bus, or a UART device; the replay of a candump log."""

    add_arguments = staticmethod(add_arguments)
    run = staticmethod(run)


class StepfocCommands(CommandHooks):
    """What the commands ask of the STEPFOC family (grippers.backends.CommandHooks)."""

    sim_names = ("msg", "stepfoc")  # `grippers sim msg` (the gripper's name) or the family's
    sim_help = "simulate MSG grippers (STEPFOC) as CAN nodes (can://IF/CH?node=N) or a UART device (pty)"
    sim_example = (
        "grippers sim msg --listen 'can://udp_multicast/239.74.163.2?node=0'\n"
        "         grippers sim msg --listen 'can://socketcan/vcan0?node=0,1,2'\n"
        "         grippers sim msg --listen pty --part-width 40\n"
        "         grippers sim msg --replay session.log --listen can://socketcan/vcan0   (a candump log)"
    )
    settings_options = stepfoc_settings.OPTIONS

    def bare_forms(self) -> dict[str, tuple[int, str]]:
        """A bare transport's URL as an MSG's (the "did you mean" of a mistyped target), ranked."""
        return {"serial": (20, "stepfoc+serial://{rest}"), "can": (10, "stepfoc+can://{rest}?node=0")}

    def probe_candidates(self, transport: str, where: Any, options: dict[str, Any]) -> list[ProbeCandidate]:
        """``grippers probe`` on a bare transport: the UART on a serial port at the profile model's speed,
        every node on a CAN bus (each with its own bus connection, so the nodes are asked in parallel)."""
        from .stepfoc_profile import MAX_NODE, StepfocTransport

        if transport == "serial":
            baud = StepfocTransport().baudrate
            return [ProbeCandidate(f"stepfoc+serial://{where.serial_port}?baudrate={baud}", order=20)]
        if transport == "can":
            extra = bus_query(options)
            base = f"stepfoc+can://{where.interface}/{where.channel}"
            return [ProbeCandidate(f"{base}?node={node}{extra}", order=10) for node in range(MAX_NODE + 1)]
        return []

    def raw_probe(self, transport: str) -> RawProbe | None:
        if transport != "serial":
            return None
        from grippers.drivers.stepfoc import probe as stepfoc_probe

        return RawProbe(stepfoc_probe.identify_request())

    def dissector(self) -> Dissector:
        """``grippers monitor``: STEPFOC CAN frames (its captures are candump logs)."""
        from grippers.drivers.stepfoc.dissect import StepfocCanDissector

        return Dissector(StepfocCanDissector.protocol, can=lambda _o: StepfocCanDissector())

    def read_settings(self, gripper: Any) -> dict[str, Any]:
        return stepfoc_settings.read_values(gripper.driver)

    def check_settings(self, gripper: Any, args: argparse.Namespace) -> None:
        stepfoc_settings.check_values(gripper, args)

    def change_settings(self, gripper: Any, args: argparse.Namespace, changed: list[str]) -> str | None:
        return stepfoc_settings.change_values(gripper, args, changed)

    def selftest_checks(self, gripper: Any, add: Callable[..., None]) -> None:
        stepfoc_settings.selftest_checks(gripper, add)

    def sim_command(self) -> StepfocSim:
        return StepfocSim()
