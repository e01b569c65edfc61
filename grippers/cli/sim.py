"""``grippers sim wsg|msg``: serve a simulated gripper over a real transport."""

from __future__ import annotations

import argparse
import importlib

HELP = "run a simulated gripper that speaks the real protocol over TCP, UDP, a pty or a CAN bus"
EXAMPLE = "grippers sim wsg --listen tcp://127.0.0.1:1000"

FAMILIES = {"wsg": ".sim_wsg", "msg": ".sim_msg"}  # modules of this package


def add_arguments(parser: argparse.ArgumentParser) -> None:
    sub = parser.add_subparsers(dest="family", metavar="FAMILY", required=True)
    for name, module_name in FAMILIES.items():
        module = importlib.import_module(module_name, __package__)
        sp = sub.add_parser(
            name,
            help=module.HELP,
            description=module.HELP,
            epilog=f"Example: {module.EXAMPLE}",
            formatter_class=argparse.RawDescriptionHelpFormatter,  # the examples, one per line
        )
        module.add_arguments(sp)
        sp.set_defaults(_family_module=module)


def run(args: argparse.Namespace) -> int:
    return int(args._family_module.run(args) or 0)
