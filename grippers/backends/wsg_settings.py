"""The WSG's device settings for ``grippers settings`` and ``selftest`` (the family's command hooks,
wsg_cli.WsgCommands): temperature, soft limits, device tag, acceleration, force limit, finger information (WSG
manual 4.0.x §3.3-§3.5 and §3.6, commands 30h-36h, 40h, 52h/53h, 60h-63h)."""

from __future__ import annotations

import argparse
import warnings
from collections.abc import Callable
from typing import Any

from ..cli.settings_cmd import try_read
from ..errors import GripperWarning

FORCE_LIMIT_LASTS = (
    "the force limit holds until the next grasp: the WSG grips with its force limit (GRIP 25h has no force "
    "field), so every grasp sets it to the grasp's force first (the profile's default_force_n when none is "
    "given; WSG manual 4.0.x §3.2.6, §3.3.3)"
)
"""Said when ``--force-limit`` is set (issue 39 §2): a user who sets a low limit and then grasps harder would
otherwise believe the limit still guards the part."""


def read_values(client: Any) -> dict[str, Any]:
    def soft() -> dict[str, float]:
        limits = client.soft_limits()
        return {"min_mm": round(limits.minus, 3), "max_mm": round(limits.plus, 3)}

    def finger(n: int) -> dict[str, Any]:
        info = client.finger_info(n)
        kind = info.finger_type
        return {"type": getattr(kind, "name", str(kind)).lower(), "data_size": info.data_size}

    return {
        "temperature_c": try_read(lambda: round(client.temperature(), 1)),
        "acceleration_mm_s2": try_read(lambda: round(client.acceleration(), 3)),
        "force_limit_n": try_read(lambda: round(client.force_limit(), 3)),
        "soft_limits": try_read(soft),
        "device_tag": try_read(client.device_tag),
        "finger_1": try_read(lambda: finger(1)),
        "finger_2": try_read(lambda: finger(2)),
    }


def check_values(gripper: Any, args: argparse.Namespace) -> None:
    """Every requested WSG value against the profile, before anything is sent (issue 23 §3: a tag was
    written, then an absurd acceleration went out or failed half-way)."""
    from grippers.drivers.numbers import finite
    from grippers.errors import LimitError

    mech = gripper.profile.mechanics
    if args.acceleration is not None:
        finite(
            args.acceleration,
            "acceleration (mm/s²)",
            low=mech.min_accel_mm_s2,
            high=mech.max_accel_mm_s2,
            device=gripper.name,
            command="set_acceleration",
            error=LimitError,
        )
    if args.force_limit is not None:
        gripper.check(force=args.force_limit, command="force_limit")  # the profile's range
    if args.soft_limits:
        lo, hi = args.soft_limits
        for value in (lo, hi):
            gripper.check(width=value / 1000, command="set_soft_limits")  # the API's own width rule
        if lo >= hi:
            raise LimitError(
                f"soft limits {lo:g} .. {hi:g} mm: the first must be below the second",
                device=gripper.name,
                command="set_soft_limits",
            )


def change_values(gripper: Any, args: argparse.Namespace, changed: list[str]) -> None:
    from ..cli.output import mm_to_m

    client = gripper.driver
    if args.clear_soft_limits:
        gripper.clear_soft_limits()
        changed.append("soft_limits")
    if args.soft_limits:
        lo, hi = args.soft_limits
        gripper.set_soft_limits(mm_to_m(lo), mm_to_m(hi))  # the API checks them against the stroke
        changed.append("soft_limits")
    if args.tag is not None:
        gripper.set_device_tag(args.tag)
        changed.append("device_tag")
    if args.acceleration is not None:
        client.set_acceleration(args.acceleration)
        changed.append("acceleration_mm_s2")
    if args.force_limit is not None:
        client.set_force_limit(args.force_limit)
        changed.append("force_limit_n")
        warnings.warn(FORCE_LIMIT_LASTS, GripperWarning, stacklevel=2)


# The options of `grippers settings` a WSG takes (WsgCommands.settings_options).
OPTIONS = ("soft_limits", "clear_soft_limits", "tag", "acceleration", "force_limit")


def selftest_checks(gripper: Any, add: Callable[..., None]) -> None:
    """``grippers selftest``'s WSG lines: the stored acceleration, force limit and soft limits."""
    values = read_values(gripper.driver)
    accel = values.get("acceleration_mm_s2")
    mech = gripper.profile.mechanics
    if isinstance(accel, float) and mech.min_accel_mm_s2 is not None and mech.max_accel_mm_s2 is not None:
        ok = mech.min_accel_mm_s2 <= accel <= mech.max_accel_mm_s2
        add(
            "acceleration",
            f"{accel:g} mm/s²",
            f"{mech.min_accel_mm_s2:g}..{mech.max_accel_mm_s2:g} mm/s²",
            "PASS" if ok else "WARN",
        )
    force = values.get("force_limit_n")
    if isinstance(force, float):
        add("force limit", f"{force:g} N", f"<= {gripper.limits.max_force:g} N", "INFO")
    soft = values.get("soft_limits")
    if isinstance(soft, dict) and "min_mm" in soft:
        add(
            "soft limits",
            f"{soft['min_mm']:g}..{soft['max_mm']:g} mm",
            "not set",
            "WARN",
            "the device refuses motion outside them",
        )
    else:
        add("soft limits", "not set", "not set", "PASS")
