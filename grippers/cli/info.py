"""``grippers info URL``: what the gripper is (vendor, model, firmware, serial) and its limits."""

from __future__ import annotations

import argparse
from typing import Any

from .common import add_common, add_target, open_gripper
from .logs import issued_warnings
from .output import EXIT_OK, INFO_SCHEMA_ID, fmt_num, info_dict, key_values, write_json
from .profile_notes import replaced_note

HELP = "show vendor, model, firmware, serial number and limits of a gripper"
EXAMPLE = (
    "grippers info sim:// --json\n         grippers info FAMILY+tcp://192.168.1.20   (your gripper's URL)"
)


def add_arguments(parser: argparse.ArgumentParser) -> None:
    add_target(parser)
    add_common(parser)


def render(info: dict[str, Any]) -> str:
    lim = info["limits"]
    pairs: list[tuple[str, Any]] = [
        ("vendor", info["vendor"]),
        ("model", info["model"]),
        ("family", info["family"]),
        ("firmware", info["firmware"]),
        ("hardware", info["hardware"]),
        ("serial", info["serial"]),
        ("profile", info["profile"]),
        ("width", f"{fmt_num(lim['min_width_mm'], '')} .. {fmt_num(lim['max_width_mm'], 'mm')}"),
        ("speed", f"{fmt_num(lim['min_speed_mm_s'], '')} .. {fmt_num(lim['max_speed_mm_s'], 'mm/s')}"),
        ("force", f"{fmt_num(lim['min_force_n'], '')} .. {fmt_num(lim['max_force_n'], 'N')}"),
    ]
    if lim["max_current_a"] is not None:
        pairs.append(("max current", fmt_num(lim["max_current_a"], "A", 3)))
    extra = dict(info.get("extra") or {})
    warnings = [str(w) for w in extra.pop("warnings", None) or []]
    pairs += [(str(k), v) for k, v in extra.items()]
    # What the backend had to assume (an MSG's model, limits it ignored), one line each, where it is seen.
    return "\n".join([key_values(pairs), *(f"warning: {w}" for w in warnings)])


def run(args: argparse.Namespace) -> int:
    gripper = open_gripper(args)
    try:
        info = info_dict(gripper.info())
    finally:
        gripper.close()
    # A plugin's wsg50.toml with 800 N where the built-in says 80 N: the limits shown are that file's.
    replaced = replaced_note(info["profile"])
    if args.json:
        warnings = [*issued_warnings(), *([replaced] if replaced else [])]
        write_json({"schema": INFO_SCHEMA_ID, "target": args.target, "info": info, "warnings": warnings})
    else:
        print(render(info))
        if replaced:
            print(f"warning: {replaced}")
    return EXIT_OK
