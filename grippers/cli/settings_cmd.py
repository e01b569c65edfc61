"""``grippers settings URL``: read, and change, what a gripper stores besides its motion.

WSG: temperature, soft limits, device tag, acceleration, force limit, finger information (WSG manual 4.0.x
§3.3-§3.5 and §3.6, commands 30h-36h, 40h, 52h/53h, 60h-63h). MSG on a STEPFOC driver: temperature, supply
voltage and the CAN node id, which can be changed (command 11) and saved to flash (command 13) behind a
confirmation, because a node id that no program expects makes the gripper disappear from the bus.
Device units are shown as the devices use them (mm, mm/s², N, °C).
"""

from __future__ import annotations

import argparse
import sys
from typing import Any

from .common import add_common, add_target, non_negative_float, open_gripper, positive_float
from .output import EXIT_OK, SETTINGS_SCHEMA_ID, UsageError, key_values, write_json

HELP = "show or change device settings: WSG soft limits, tag, acceleration, force limit; MSG node id"
EXAMPLE = (
    "grippers settings wsg+tcp://192.168.1.20\n"
    "         grippers settings wsg+tcp://192.168.1.20 --soft-limits 10 90 --tag bench-2 --json\n"
    "         grippers settings wsg+tcp://192.168.1.20 --acceleration 500 --force-limit 40\n"
    "         grippers settings 'stepfoc+can://socketcan/can0?node=0' --node-id 3   (asks, then saves)"
)

MAX_NODE = 15  # 4-bit node id (MSG manual, "Bits 10 - 7 of CAN ID"; docs/protocols.md §2)


def add_arguments(parser: argparse.ArgumentParser) -> None:
    add_target(parser)
    wsg = parser.add_argument_group("WSG")
    wsg.add_argument(
        "--soft-limits",
        nargs=2,
        type=non_negative_float,
        metavar=("MIN_MM", "MAX_MM"),
        help="set the soft limits the device enforces",
    )
    wsg.add_argument("--clear-soft-limits", action="store_true", help="remove the soft limits")
    wsg.add_argument("--tag", metavar="TEXT", help="set the device tag (a name stored in the gripper)")
    wsg.add_argument("--acceleration", type=positive_float, metavar="MM_S2", help="set the acceleration")
    wsg.add_argument("--force-limit", type=positive_float, metavar="N", help="set the grip force limit")
    msg = parser.add_argument_group("MSG (STEPFOC over CAN)")
    msg.add_argument("--node-id", type=int, metavar="N", help=f"change the CAN node id (0..{MAX_NODE})")
    msg.add_argument(
        "--no-save", dest="save", action="store_false", help="with --node-id: do not save it (lost at reset)"
    )
    msg.add_argument("-y", "--yes", action="store_true", help="with --node-id: do not ask for confirmation")
    add_common(parser)


def _try(read: Any) -> Any:
    """A value, or the reason the device did not give one ('not set', 'not supported')."""
    from grippers.errors import CommandFailed, GripperError, NotSupported

    try:
        return read()
    except NotSupported:
        return {"unavailable": "not supported by this device"}
    except CommandFailed as exc:
        if exc.status_name == "E_NOT_AVAILABLE":  # nothing stored (no soft limits, no tag)
            return {"unavailable": "not set"}
        return {"unavailable": exc.message}
    except GripperError as exc:
        return {"unavailable": exc.message}


def _wsg_read(client: Any) -> dict[str, Any]:
    def soft() -> dict[str, float]:
        limits = client.soft_limits()
        return {"min_mm": round(limits.minus, 3), "max_mm": round(limits.plus, 3)}

    def finger(n: int) -> dict[str, Any]:
        info = client.finger_info(n)
        kind = info.finger_type
        return {"type": getattr(kind, "name", str(kind)).lower(), "data_size": info.data_size}

    return {
        "temperature_c": _try(lambda: round(client.temperature(), 1)),
        "acceleration_mm_s2": _try(lambda: round(client.acceleration(), 3)),
        "force_limit_n": _try(lambda: round(client.force_limit(), 3)),
        "soft_limits": _try(soft),
        "device_tag": _try(client.device_tag),
        "finger_1": _try(lambda: finger(1)),
        "finger_2": _try(lambda: finger(2)),
    }


def _msg_read(driver: Any) -> dict[str, Any]:
    out: dict[str, Any] = {}
    node = getattr(driver, "node", None)
    if node is not None:
        out["node_id"] = node
    if hasattr(driver, "temperature"):
        out["temperature_c"] = _try(driver.temperature)
    if hasattr(driver, "bus_voltage"):
        out["supply_v"] = _try(lambda: round(driver.bus_voltage() / 1000.0, 3))
    return out


def _confirm(question: str, yes: bool) -> None:
    if yes:
        return
    if not sys.stdin.isatty():
        raise UsageError(f"{question}: add --yes to confirm (no terminal to ask on)")
    answer = input(f"{question} [y/N] ").strip().lower()
    if answer not in ("y", "yes"):
        raise UsageError("not confirmed; nothing changed")


def _change_wsg(gripper: Any, args: argparse.Namespace, changed: list[str]) -> None:
    from .output import mm_to_m

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
        gripper.check(force=args.force_limit, command="force_limit")  # the profile's range first
        client.set_force_limit(args.force_limit)
        changed.append("force_limit_n")


def _change_msg(gripper: Any, args: argparse.Namespace, changed: list[str]) -> str | None:
    driver = gripper.driver
    if not 0 <= args.node_id <= MAX_NODE:
        raise UsageError(f"--node-id {args.node_id}: outside 0..{MAX_NODE}")
    if not hasattr(driver, "set_node_id"):
        raise UsageError("--node-id needs an MSG on CAN (stepfoc+can://...); the UART has no node id")
    old = driver.node
    saved = " and save it in the driver's flash" if args.save else " until the next reset"
    _confirm(f"change node {old} to node {args.node_id}{saved}", args.yes)
    driver.set_node_id(args.node_id)
    if not driver.ping():  # the handle follows the node: the node must answer at its new id
        from grippers.errors import GripperTimeout

        raise GripperTimeout(
            f"no answer at node {args.node_id} after the change", device=gripper.name, command="set_can_id"
        )
    if args.save:
        driver.save_config()
    changed.append("node_id")
    base, _, query = gripper.url.partition("?")
    params = [p for p in query.split("&") if p and not p.startswith("node=")]
    return base + "?" + "&".join([f"node={args.node_id}", *params])


def run(args: argparse.Namespace) -> int:
    wsg_changes = (
        args.soft_limits or args.clear_soft_limits or args.tag is not None or args.acceleration is not None
    ) or args.force_limit is not None
    if args.soft_limits and args.clear_soft_limits:
        raise UsageError("give --soft-limits or --clear-soft-limits, not both")
    gripper = open_gripper(args)
    changed: list[str] = []
    new_url = None
    try:
        family = gripper.info().family
        if family == "wsg":
            if args.node_id is not None:
                raise UsageError("--node-id is for an MSG on CAN; a WSG has no node id")
            _change_wsg(gripper, args, changed)
            values = _wsg_read(gripper.driver)
        elif family == "stepfoc":
            if wsg_changes:
                raise UsageError("--soft-limits, --tag, --acceleration and --force-limit are WSG settings")
            if args.node_id is not None:
                new_url = _change_msg(gripper, args, changed)
            values = _msg_read(gripper.driver)
        else:
            raise UsageError(f"no device settings known for the {family} family")
    finally:
        gripper.close()
    document = {
        "schema": SETTINGS_SCHEMA_ID,
        "target": args.target,
        "family": family,
        "settings": values,
        "changed": changed,
        "url": new_url or args.target,
    }
    if args.json:
        write_json(document)
    else:
        print(render(document))
    return EXIT_OK


def _text(value: Any, unit: str = "") -> str:
    if isinstance(value, dict) and "unavailable" in value:
        return f"- ({value['unavailable']})"
    if isinstance(value, dict) and "min_mm" in value:
        return f"{value['min_mm']:.1f} .. {value['max_mm']:.1f} mm"
    if isinstance(value, dict) and "type" in value:
        return f"{value['type']} ({value['data_size']} data bytes)"
    if isinstance(value, float):
        return f"{value:.1f} {unit}".strip()
    return f"{value} {unit}".strip()


LABELS = {
    "temperature_c": ("temperature", "°C"),
    "acceleration_mm_s2": ("acceleration", "mm/s²"),
    "force_limit_n": ("force limit", "N"),
    "soft_limits": ("soft limits", ""),
    "device_tag": ("device tag", ""),
    "finger_1": ("finger 1", ""),
    "finger_2": ("finger 2", ""),
    "node_id": ("node id", ""),
    "supply_v": ("supply", "V"),
}


def render(document: dict[str, Any]) -> str:
    pairs = []
    for key, value in document["settings"].items():
        label, unit = LABELS.get(key, (key, ""))
        pairs.append((label, _text(value, unit)))
    if document["changed"]:
        pairs.append(("changed", ", ".join(document["changed"])))
    if document["url"] != document["target"]:
        pairs.append(("open it with", document["url"]))
    return key_values(pairs)
