"""A SCHUNK unit's stored settings for ``grippers settings`` and ``selftest`` (its command hooks,
schunk_cli.py), and its soft limits (``Gripper.set_soft_limits``): the unit's own minimum and
maximum position, 0x0600 and 0x0608, writable floats in mm (SCHUNK's writable_parameters.json). The unit
refuses a target outside them ("command not feasible"); cleared, they span 0 .. max_phys_stroke (0x0588)."""

from __future__ import annotations

import argparse
from typing import Any, Protocol

from grippers.drivers.schunk.client import SchunkClient
from grippers.drivers.schunk.protocol import BY_NAME, encode

from .schunk_profile import SchunkProfile


class Holder(Protocol):
    """What the soft limits ask of the :class:`~grippers.backends.schunk.SchunkDevice` (declared here, so this
    module does not import the device's, which imports this one)."""

    client: SchunkClient
    profile: SchunkProfile


class SchunkSoftLimits:
    """The ``soft_limits`` feature: writes min_pos/max_pos, and keeps the client's copy of them current."""

    def __init__(self, device: Holder) -> None:
        self.device = device

    def set(self, min_width: float | None, max_width: float | None) -> None:
        client = self.device.client
        if min_width is None or max_width is None:
            stroke = client.parameters.get("max_phys_stroke")
            lo_mm, hi_mm = (
                0.0,
                float(stroke) if isinstance(stroke, float) else self.device.profile.mechanics.max_width_mm,
            )
        else:
            lo_mm, hi_mm = min_width * 1000, max_width * 1000
        for name, value in (("min_pos", lo_mm), ("max_pos", hi_mm)):
            p = BY_NAME[name]
            client.write_raw(name, encode(p.inst, value, client.fieldbus), "set_soft_limits")
            client.parameters[name] = value


def read_values(gripper: Any) -> dict[str, Any]:
    from ..cli.settings_cmd import try_read

    client = gripper.driver

    def value(name: str) -> Any:
        return try_read(lambda: round(float(client.read_parameter(name, "settings")), 3))

    return {
        "temperature_c": value("meas_lgc_temp"),
        "soft_limits": {"min_mm": value("min_pos"), "max_mm": value("max_pos")},
        "max_stroke_mm": value("max_phys_stroke"),
        "release_delta_mm": value("wp_release_delta"),
        "module_type": client.module_type,
        "fieldbus": client.fieldbus.short,
    }


# The options of `grippers settings` a SCHUNK unit takes: its position limits, as soft limits.
OPTIONS = ("soft_limits", "clear_soft_limits")


def check_values(gripper: Any, args: argparse.Namespace) -> None:
    if args.soft_limits:
        lo, hi = args.soft_limits
        gripper.check(width=lo / 1000, command="set_soft_limits")
        gripper.check(width=hi / 1000, command="set_soft_limits")


def change_values(gripper: Any, args: argparse.Namespace, changed: list[str]) -> None:
    if args.clear_soft_limits:
        gripper.clear_soft_limits()
        changed.append("soft_limits")
    if args.soft_limits:
        lo, hi = args.soft_limits
        gripper.set_soft_limits(lo / 1000, hi / 1000)
        changed.append("soft_limits")
