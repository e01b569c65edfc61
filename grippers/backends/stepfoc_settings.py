"""An MSG's device settings on a STEPFOC driver for ``grippers settings`` and ``selftest`` (the family's
command hooks, stepfoc_cli.StepfocCommands): temperature, supply voltage, the CAN node id (command 11), the
watchdog (15) and the heartbeat (30), which are saved to flash (command 13) behind a confirmation: a node id
that no program expects makes the gripper disappear from the bus, and a saved watchdog or heartbeat acts at
every power-up after (STEPFOC firmware, src/EEPROM.cpp stores both periods; src/communication_CAN.cpp
``CAN_watchdog`` is fed only by 61s, data packs and remote requests)."""

from __future__ import annotations

import argparse
import sys
from collections.abc import Callable
from typing import Any

from ..cli.output import UsageError
from ..cli.settings_cmd import MAX_PERIOD_MS, confirm, try_read
from .stepfoc_profile import MAX_NODE


def read_values(driver: Any) -> dict[str, Any]:
    out: dict[str, Any] = {}
    node = getattr(driver, "node", None)
    if node is not None:
        out["node_id"] = node
    if hasattr(driver, "temperature"):
        out["temperature_c"] = try_read(driver.temperature)
    if hasattr(driver, "bus_voltage"):
        out["supply_v"] = try_read(lambda: round(driver.bus_voltage() / 1000.0, 3))
    return out


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


def check_values(gripper: Any, args: argparse.Namespace) -> None:
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


def change_values(gripper: Any, args: argparse.Namespace, changed: list[str]) -> str | None:
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
        confirm(question, args.yes)
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


# The options of `grippers settings` an MSG takes (StepfocCommands.settings_options).
OPTIONS = ("node_id", "watchdog", "heartbeat", "save")


def selftest_checks(gripper: Any, add: Callable[..., None]) -> None:
    """``grippers selftest``'s MSG lines: the node id, the driver's error flags, watchdog and heartbeat."""
    driver = gripper.driver
    values = read_values(driver)
    if "node_id" in values:
        add("node id", str(values["node_id"]), "-", "INFO")
    if hasattr(driver, "error_state"):
        es = driver.error_state()
        names = [n for n in ("temperature", "encoder", "vbus", "driver", "velocity", "current", "estop")]
        active = [n for n in names if getattr(es, n, False)]
        add(
            "driver errors (26)",
            ", ".join(active) or "none",
            "none",
            "WARN" if active else "PASS",
        )
        tripped = bool(getattr(es, "watchdog", False))
        add(
            "watchdog",
            "tripped" if tripped else "not tripped",
            "not tripped",
            "WARN" if tripped else "PASS",
            "the node cannot report its watchdog period; grippers settings --watchdog 0 --save clears it",
        )
        heard = getattr(driver, "last_heartbeat", None) is not None
        add(
            "heartbeat",
            "heard" if heard else "not heard",
            "-",
            "INFO",
            "sent only after silence, so a polled node sends none",
        )
