"""The SCHUNK family's command hooks (:class:`SchunkCommands`, the backend's ``commands``): the words of
the generic ``grippers sim schunk``, the probe's candidate on a bare serial port, the monitor's dissector
and the unit's settings (its position limits, as soft limits: schunk_settings.py)."""

from __future__ import annotations

import argparse
from typing import Any

from . import schunk_settings
from .command_hooks import CommandHooks, Dissector, ProbeCandidate
from .schunk_profile import FALLBACK_PROFILE


class SchunkCommands(CommandHooks):
    """What the commands ask of the SCHUNK family (grippers.backends.CommandHooks)."""

    default_profile = FALLBACK_PROFILE
    sim_help = "simulate a SCHUNK EGU/EGK unit: its web API on http://HOST:PORT, or Modbus RTU on a pty"
    sim_example = (
        "grippers sim schunk --listen http://127.0.0.1:8080 --model egu-60\n"
        "         grippers sim schunk --listen pty --model egk-25"
    )
    settings_options = schunk_settings.OPTIONS

    def bare_forms(self) -> dict[str, tuple[int, str]]:
        return {"serial": (40, "schunk+serial://{rest}")}

    def dissector(self) -> Dissector:
        """``grippers monitor``: a unit's Modbus RTU frames (a capture or stdin), instances named and the
        process data decoded."""
        from grippers.drivers.schunk.dissect import PROTOCOL, SchunkDissector

        return Dissector(PROTOCOL, stream=SchunkDissector)

    def probe_candidates(self, transport: str, where: Any, options: dict[str, Any]) -> list[ProbeCandidate]:
        """``grippers probe`` on a bare serial port: Modbus RTU at SCHUNK's device id 12 (the unit's module
        type, 0x0500, then says which gripper it is)."""
        if transport != "serial" or not where.serial_port:
            return []
        return [ProbeCandidate(f"schunk+serial://{where.serial_port}", order=40)]

    def read_settings(self, gripper: Any) -> dict[str, Any]:
        return schunk_settings.read_values(gripper)

    def check_settings(self, gripper: Any, args: argparse.Namespace) -> None:
        schunk_settings.check_values(gripper, args)

    def change_settings(self, gripper: Any, args: argparse.Namespace, changed: list[str]) -> None:
        schunk_settings.change_values(gripper, args, changed)
