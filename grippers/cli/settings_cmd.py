"""``grippers settings URL``: read, and change, what a gripper stores besides its motion.

WSG: temperature, soft limits, device tag, acceleration, force limit, finger information (WSG manual 4.0.x
§3.3-§3.5 and §3.6, commands 30h-36h, 40h, 52h/53h, 60h-63h). MSG on a STEPFOC driver: temperature, supply
voltage, the CAN node id (command 11), the watchdog (15) and the heartbeat (30), which are saved to flash
(command 13) behind a confirmation: a node id that no program expects makes the gripper disappear from the
bus, and a saved watchdog or heartbeat acts at every power-up after (STEPFOC firmware, src/EEPROM.cpp stores
both periods; src/communication_CAN.cpp ``CAN_watchdog`` is fed only by 61s, data packs and remote requests).
Device units are shown as the devices use them (mm, mm/s², N, °C).

Every value is checked, and every conflict found, before the first byte that changes the device is sent: a
refused setting never leaves half of a command line applied.
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
    "         grippers settings 'stepfoc+can://socketcan/can0?node=0' --node-id 3   (asks, then saves)\n"
    "         grippers settings 'stepfoc+can://socketcan/can0?node=0' --watchdog 0 --heartbeat 0 --save"
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
        "--watchdog",
        type=period_ms,
        metavar="MS",
        help="node raises 'timeout' and idles after MS ms without a 61, data pack or remote request (0 off)",
    )
    msg.add_argument(
        "--heartbeat",
        type=period_ms,
        metavar="MS",
        help="node sends a heartbeat after MS ms of silence (0 off)",
    )
    msg.add_argument(
        "--save",
        dest="save",
        action="store_true",
        default=None,
        help="save node id, watchdog and heartbeat to flash (default with --node-id; asks first)",
    )
    msg.add_argument(
        "--no-save", dest="save", action="store_false", help="with --node-id: do not save it (lost at reset)"
    )
    msg.add_argument(
        "-y", "--yes", action="store_true", help="do not ask before changing a node id or saving"
    )
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


def _check_wsg(gripper: Any, args: argparse.Namespace) -> None:
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
        client.set_force_limit(args.force_limit)
        changed.append("force_limit_n")


MAX_PERIOD_MS = 0xFFFFFFFF  # u32 milliseconds (commands 15 and 30, docs/protocols.md §2)


def period_ms(text: str) -> int:
    """``--watchdog`` and ``--heartbeat``: whole milliseconds, 0..2³²-1, refused while the arguments are
    parsed, with the number and the range as written (issue 33 §3: "4.29497e+09 is above 4.29497e+09")."""
    from grippers.drivers.numbers import finite
    from grippers.errors import LimitError

    try:
        value = int(text, 10)
    except ValueError:
        raise argparse.ArgumentTypeError(f"not a whole number of milliseconds: {text!r}") from None
    try:
        finite(value, "period", low=0, high=MAX_PERIOD_MS)
    except LimitError as exc:
        raise argparse.ArgumentTypeError(exc.message) from None
    return value


def _period(value: int | None, name: str, device: str) -> int | None:
    from grippers.drivers.numbers import finite
    from grippers.errors import LimitError

    if value is None:
        return None
    return int(finite(value, name, low=0, high=MAX_PERIOD_MS, device=device, command=name, error=LimitError))


def power_up_notes(watchdog_ms: int | None, heartbeat_ms: int | None, heartbeat_heard: bool) -> list[str]:
    """What a save (13) makes the node do at every power-up after, and how to undo it.

    The node cannot report its watchdog or heartbeat period (no command reads them back), so a period this
    command did not set is unknown: the note then says that whatever a program set since power-up is saved
    too, and how to save both off."""
    notes = []
    if watchdog_ms:
        notes.append(
            f"the watchdog ({watchdog_ms} ms) is saved: after every power-up the node raises 'timeout' and "
            f"idles unless something sends it a 61, a data pack or a remote request over CAN at least every "
            f"{watchdog_ms} ms (UART traffic does not feed it); clear it with --watchdog 0 --save"
        )
    if heartbeat_ms or (heartbeat_ms is None and heartbeat_heard):
        period = f" ({heartbeat_ms} ms)" if heartbeat_ms else " (heard from this node)"
        notes.append(
            f"the heartbeat{period} is saved: after every power-up the node sends a heartbeat frame "
            "(command 9) after each period without another frame from it; clear it with --heartbeat 0 --save"
        )
    unknown = [
        name for name, value in (("watchdog", watchdog_ms), ("heartbeat", heartbeat_ms)) if value is None
    ]
    if heartbeat_heard and "heartbeat" in unknown:
        unknown.remove("heartbeat")
    if unknown:
        notes.append(
            f"the node cannot report its {' and '.join(unknown)} period: a period set since power-up (by a "
            f"program) is saved too; add --{' 0 --'.join(unknown)} 0 to save it off"
        )
    return notes


def _check_msg(gripper: Any, args: argparse.Namespace) -> None:
    """Everything that can refuse the MSG changes, before the first frame that changes the node."""
    driver = gripper.driver
    wants = args.node_id is not None or args.watchdog is not None or args.heartbeat is not None or args.save
    if wants and not hasattr(driver, "set_node_id"):
        raise UsageError(
            "--node-id, --watchdog, --heartbeat and --save need an MSG on CAN (stepfoc+can://...); "
            "the UART has none of them"
        )
    _period(args.watchdog, "watchdog", gripper.name)
    _period(args.heartbeat, "heartbeat", gripper.name)
    if args.node_id is None:
        return
    if not 0 <= args.node_id <= MAX_NODE:
        raise UsageError(f"--node-id {args.node_id}: outside 0..{MAX_NODE}")
    if args.node_id != driver.node and driver.bus.node(args.node_id).ping(timeout=args.timeout):
        # Two nodes with one id both answer every frame meant for either: refuse before anything changes.
        raise UsageError(
            f"--node-id {args.node_id}: another node on this bus already answers as node {args.node_id}; "
            "nothing changed (grippers probe lists the ids in use)"
        )


def _change_msg(gripper: Any, args: argparse.Namespace, changed: list[str]) -> str | None:
    from grippers.errors import GripperTimeout

    driver = gripper.driver
    save = args.save if args.save is not None else args.node_id is not None
    old = driver.node
    plan = []
    if args.node_id is not None:
        plan.append(f"change node {old} to node {args.node_id}")
    if args.watchdog is not None:
        plan.append(f"set the watchdog to {args.watchdog} ms" if args.watchdog else "switch the watchdog off")
    if args.heartbeat is not None:
        plan.append(
            f"set the heartbeat to {args.heartbeat} ms" if args.heartbeat else "switch the heartbeat off"
        )
    if not plan and not save:
        return None
    if save:
        plan.append("save it in the driver's flash" if plan else "save the node's settings in its flash")
        heard = driver.last_heartbeat is not None
        for note in power_up_notes(args.watchdog, args.heartbeat, heard):
            print(f"grippers settings: note: {note}", file=sys.stderr)
    elif args.node_id is not None:
        plan.append("until the next reset")
    question = ", ".join(plan)
    if args.node_id is not None or save:  # changes that outlive this session, or lose the node, are asked
        _confirm(question, args.yes)
    if args.watchdog is not None:
        driver.watchdog(args.watchdog)
        changed.append("watchdog_ms")
    if args.heartbeat is not None:
        driver.heartbeat(args.heartbeat)
        changed.append("heartbeat_ms")
    new_url = None
    if args.node_id is not None:
        driver.set_node_id(args.node_id)
        if not driver.ping():  # the handle follows the node: the node must answer at its new id
            raise GripperTimeout(
                f"no answer at node {args.node_id} after the change",
                device=gripper.name,
                command="set_can_id",
            )
        changed.append("node_id")
        from grippers.drivers.urls import with_params

        new_url = with_params(gripper.url, node=args.node_id)
    if save:
        driver.save_config()
    return new_url


def has_vendor_driver(gripper: Any) -> bool:
    """Whether ``gripper.driver`` is a device client (settings are its vendor extras); a served gripper's
    (zenoh://) is a network session, which carries motion and state but not the settings commands."""
    from grippers.drivers.stepfoc.can_client import StepfocNode
    from grippers.drivers.stepfoc.uart_client import StepfocUart
    from grippers.drivers.wsg.client import WsgClient

    return isinstance(gripper.driver, WsgClient | StepfocNode | StepfocUart)


def _refuse_remote(gripper: Any) -> None:
    """Refuse a served gripper before anything is written (issue 23 §3: the tag went out over the API, then
    the acceleration failed with an AttributeError)."""
    if not has_vendor_driver(gripper):
        raise UsageError(
            f"{gripper.url}: device settings are not served over the network; run grippers settings on the "
            "machine that serves this gripper, with the device's own URL"
        )


def run(args: argparse.Namespace) -> int:
    wsg_changes = (
        args.soft_limits or args.clear_soft_limits or args.tag is not None or args.acceleration is not None
    ) or args.force_limit is not None
    msg_changes = (
        args.node_id is not None or args.watchdog is not None or args.heartbeat is not None or bool(args.save)
    )
    if args.soft_limits and args.clear_soft_limits:
        raise UsageError("give --soft-limits or --clear-soft-limits, not both")
    gripper = open_gripper(args)
    changed: list[str] = []
    new_url = None
    try:
        _refuse_remote(gripper)
        family = gripper.info().family
        if family == "wsg":
            if msg_changes:
                raise UsageError(
                    "--node-id, --watchdog, --heartbeat and --save are MSG settings; a WSG has none"
                )
            _check_wsg(gripper, args)
            _change_wsg(gripper, args, changed)
            values = _wsg_read(gripper.driver)
        elif family == "stepfoc":
            if wsg_changes:
                raise UsageError("--soft-limits, --tag, --acceleration and --force-limit are WSG settings")
            _check_msg(gripper, args)
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
