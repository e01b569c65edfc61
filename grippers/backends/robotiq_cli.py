"""The Robotiq family's command hooks (:class:`RobotiqCommands`, the backend's ``commands``): the words of
the generic ``grippers sim robotiq``, the probe's candidates on a bare serial port and the monitor's Modbus
dissector. No device settings (the slave id and the baud rate are set with Robotiq's own software) and no
self-test lines of its own: the generic ones cover it."""

from __future__ import annotations

from typing import Any

from .command_hooks import CommandHooks, Dissector, ProbeCandidate
from .robotiq_profile import FALLBACK_PROFILE, RobotiqTransport


class RobotiqCommands(CommandHooks):
    """What the commands ask of the Robotiq family (grippers.backends.CommandHooks)."""

    default_profile = FALLBACK_PROFILE  # `grippers sim robotiq` without --model
    sim_help = (
        "simulate a Robotiq gripper: Modbus RTU on a pseudo-terminal (pty) or tcp://HOST:PORT, or the "
        "URCap's socket on urcap://HOST:PORT"
    )
    sim_example = (
        "grippers sim robotiq --listen pty --model 2f85\n"
        "         grippers sim robotiq --listen tcp://127.0.0.1:5020 --model hand-e\n"
        "         grippers sim robotiq --listen urcap://127.0.0.1:63352 --model hand-e"
    )

    def bare_forms(self) -> dict[str, tuple[int, str]]:
        return {"serial": (30, "robotiq+serial://{rest}")}  # the "did you mean" of a bare serial port

    def dissector(self) -> Dissector:
        """``grippers monitor``: Modbus RTU frames (a byte capture, or the TCP proxy to a gateway)."""
        from grippers.drivers.robotiq.dissect import PROTOCOL, ModbusDissector

        return Dissector(PROTOCOL, stream=ModbusDissector, tcp_port=RobotiqTransport().tcp_port)

    def probe_candidates(self, transport: str, where: Any, options: dict[str, Any]) -> list[ProbeCandidate]:
        """``grippers probe`` on a bare serial port: Modbus RTU at the gripper's factory slave id (9)."""
        if transport != "serial":
            return []
        url = f"robotiq+serial://{where.serial_port}?baudrate={RobotiqTransport().baudrate}"
        return [ProbeCandidate(url, order=30, protocol="modbus-rtu")]  # another family on its map: identity
