"""``grippers settings URL``: read, and change, what a gripper stores besides its motion.

What a family offers is in its backend's command hooks (``settings_options``, ``check_settings``,
``change_settings``, ``read_settings``: grippers.backends.CommandHooks); this module parses the options and
shows the result. The built-in families: WSG: temperature, soft limits, device tag, acceleration, force limit,
finger information (WSG manual 4.0.x §3.3-§3.5 and §3.6, commands 30h-36h, 40h, 52h/53h, 60h-63h). MSG on a
STEPFOC driver: temperature, supply voltage, the CAN node id (command 11), the watchdog (15) and the heartbeat
(30), which are saved to flash (command 13) behind a confirmation: a node id that no program expects makes the
gripper disappear from the bus, and a saved watchdog or heartbeat acts at every power-up after (STEPFOC
firmware, src/EEPROM.cpp stores both periods; src/communication_CAN.cpp ``CAN_watchdog`` is fed only by 61s,
data packs and remote requests). Device units are shown as the devices use them (mm, mm/s², N, °C).

Every value is checked, and every conflict found, before the first byte that changes the device is sent: a
refused setting never leaves half of a command line applied.
"""

from __future__ import annotations

import argparse
import sys
from typing import Any

from .common import add_common, add_target, non_negative_float, open_gripper, positive_float
from .output import EXIT_OK, SETTINGS_SCHEMA_ID, UsageError, key_values, write_json

HELP = "show or change device settings: soft limits, tag, acceleration, force limit, bus node id, ..."
EXAMPLE = (
    "grippers settings sim://\n"
    "         grippers settings URL\n"
    "         grippers settings URL --soft-limits 10 90 --tag bench-2 --json\n"
    "         grippers settings URL --acceleration 500 --force-limit 40\n"
    "         grippers settings 'FAMILY+can://socketcan/can0?node=0' --node-id 3   (asks, then saves)\n"
    "         grippers settings 'FAMILY+can://socketcan/can0?node=0' --watchdog 0 --heartbeat 0 --save\n"
    "         (which of these a gripper takes is its family's to say: grippers settings URL shows them)"
)

# Every option a family's ``settings_options`` may name (argparse dests): one given that the gripper's family
# does not take is refused by name before anything is sent.
SETTING_OPTIONS = (
    "soft_limits",
    "clear_soft_limits",
    "tag",
    "acceleration",
    "force_limit",
    "node_id",
    "watchdog",
    "heartbeat",
    "save",
)


def add_arguments(parser: argparse.ArgumentParser) -> None:
    add_target(parser)
    stored = parser.add_argument_group("stored in the gripper (families with them)")
    stored.add_argument(
        "--soft-limits",
        nargs=2,
        type=non_negative_float,
        metavar=("MIN_MM", "MAX_MM"),
        help="set the soft limits the device enforces",
    )
    stored.add_argument("--clear-soft-limits", action="store_true", help="remove the soft limits")
    stored.add_argument("--tag", metavar="TEXT", help="set the device tag (a name stored in the gripper)")
    stored.add_argument("--acceleration", type=positive_float, metavar="MM_S2", help="set the acceleration")
    stored.add_argument("--force-limit", type=positive_float, metavar="N", help="set the grip force limit")
    node = parser.add_argument_group("a node on a bus (families with them)")
    node.add_argument("--node-id", type=int, metavar="N", help="change the bus node id (the family's range)")
    node.add_argument(
        "--watchdog",
        type=period_ms,
        metavar="MS",
        help="node raises 'timeout' and idles after MS ms without traffic from its controller (0 off)",
    )
    node.add_argument(
        "--heartbeat",
        type=period_ms,
        metavar="MS",
        help="node sends a heartbeat after MS ms of silence (0 off)",
    )
    node.add_argument(
        "--save",
        dest="save",
        action="store_true",
        default=None,
        help="save node id, watchdog and heartbeat to flash (default with --node-id; asks first)",
    )
    node.add_argument(
        "--no-save", dest="save", action="store_false", help="with --node-id: do not save it (lost at reset)"
    )
    node.add_argument(
        "-y", "--yes", action="store_true", help="do not ask before changing a node id or saving"
    )
    add_common(parser)


def try_read(read: Any) -> Any:
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


def confirm(question: str, yes: bool) -> None:
    if yes:
        return
    if not sys.stdin.isatty():
        raise UsageError(f"{question}: add --yes to confirm (no terminal to ask on)")
    answer = input(f"{question} [y/N] ").strip().lower()
    if answer not in ("y", "yes"):
        raise UsageError("not confirmed; nothing changed")


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


def _given(args: argparse.Namespace, option: str) -> bool:
    return getattr(args, option, None) not in (None, False, [])


def _refuse_unreachable(gripper: Any, hooks: Any) -> None:
    """Refuse before anything is written: a gripper whose device client is not here (a served one: issue 23
    §3, the tag went out over the API, then the acceleration failed)."""
    if not hooks.local(gripper):
        raise UsageError(
            f"{gripper.url}: device settings are not served over the network; run grippers settings on the "
            "machine that serves this gripper, with the device's own URL"
        )


def _no_settings(family: str) -> UsageError:
    return UsageError(f"the {family} backend offers no device settings")


def run(args: argparse.Namespace) -> int:
    if args.soft_limits and args.clear_soft_limits:
        raise UsageError("give --soft-limits or --clear-soft-limits, not both")
    gripper = open_gripper(args)
    changed: list[str] = []
    new_url = None
    try:
        from grippers.backends import find_backend
        from grippers.backends.command_hooks import commands_of

        family = gripper.info().family
        hooks = commands_of(find_backend(family))
        _refuse_unreachable(gripper, hooks)
        foreign = [o for o in SETTING_OPTIONS if _given(args, o) and o not in hooks.settings_options]
        if foreign and not hooks.settings_options:
            raise _no_settings(family)
        if foreign:
            names = ", ".join("--" + o.replace("_", "-") for o in foreign)
            takes = ", ".join("--" + o.replace("_", "-") for o in hooks.settings_options)
            raise UsageError(f"{names}: not settings of a {family} gripper (it takes {takes})")
        hooks.check_settings(gripper, args)
        new_url = hooks.change_settings(gripper, args, changed)
        values = hooks.read_settings(gripper)
        if values is None:
            raise _no_settings(family)
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
