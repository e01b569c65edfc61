"""Run every benchmark and print one line per target: figure, baseline, ratio, goal, PASS/FAIL.

    .venv/bin/python benchmarks/run.py            # the full run (a few minutes)
    .venv/bin/python benchmarks/run.py --quick    # shorter runs of the same (about a minute)
    .venv/bin/python benchmarks/run.py --only 1,4 --markdown

Exit status: 0 when every target is met, 1 when one is missed, 2 when a benchmark could not run.
Each baseline is measured in the same run as its figure (see benchmarks/common.py), and docs/performance.md
explains what each target measures.
"""

from __future__ import annotations

import argparse
import sys
import time
import traceback
from collections.abc import Callable
from pathlib import Path
from typing import Any

if __package__ in (None, ""):
    sys.path.insert(0, str(Path(__file__).resolve().parent.parent))

from benchmarks.common import Result, format_table, markdown_table


def _targets() -> dict[int, Callable[[bool], list[Result]]]:
    # imported here so that `--only` loads only what it runs
    from benchmarks import aio, remote, robotiq, startup, stepfoc_bus, stepfoc_codec, wsg_client, wsg_parser

    return {
        1: wsg_parser.run,
        2: lambda quick: [wsg_client.round_trip(quick)],
        3: lambda quick: [wsg_client.state_under_load(quick)],
        4: stepfoc_codec.run,
        5: stepfoc_bus.run,
        6: startup.run,
        7: lambda quick: [wsg_client.memory(quick)],
        8: lambda quick: [remote.state_round_trip(quick)],
        9: lambda quick: [remote.publish_load(quick)],
        10: lambda quick: [remote.lease_failover(quick)],
        11: _servo,  # issue 15 (benchmarks/servo.py)
        12: _servo_remote,  # issue 21 §3: servo from a zenoh:// client, beside 11's local figures
        13: aio.run,  # issue 20 §2: the asyncio face's state() against the threaded one
        14: robotiq.run,  # issue 29 §5: a Robotiq poll's CPU against its wire time, servo over a pty
        15: _ros2_node,  # issue 34 §6: a goal through `grippers ros2` against a bare rclpy server
        16: lambda quick: [_panel().state_load(quick)],  # issue 42 §5: the panel's states and CPU
        17: lambda quick: [_panel().stop_click(quick)],  # issue 42 §5: a click on Stop to the device
        18: _schunk,  # issue 41 §5: a SCHUNK poll's CPU against the bare HTTP request and the RTU wire
    }


def _panel() -> Any:
    from benchmarks import panel

    return panel


def _servo(quick: bool) -> list[Result]:
    from benchmarks import servo

    return servo.run(quick)


def _servo_remote(quick: bool) -> list[Result]:
    from benchmarks import servo

    return servo.run_remote(quick)


def _schunk(quick: bool) -> list[Result]:
    from benchmarks import schunk

    return schunk.run(quick)


def _ros2_node(quick: bool) -> list[Result]:
    from benchmarks import ros2_node

    return ros2_node.run(quick)


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--quick", action="store_true", help="shorter runs (CI smoke; about a minute)")
    ap.add_argument("--only", help="comma-separated target numbers, e.g. 1,4")
    ap.add_argument("--markdown", action="store_true", help="also print the table as Markdown")
    args = ap.parse_args(argv)
    targets = _targets()
    chosen = sorted(targets) if not args.only else [int(t) for t in args.only.split(",")]
    unknown = [t for t in chosen if t not in targets]
    if unknown:
        ap.error(f"no target {unknown}; targets are {sorted(targets)}")
    results: list[Result] = []
    broken = False
    t0 = time.perf_counter()
    for number in chosen:
        try:
            got = targets[number](args.quick)
        except Exception as exc:  # noqa: BLE001 - report the failure as a line and run the others
            traceback.print_exc()
            got = [Result(f"{number} (error)", type(exc).__name__, "-", "-", "-", False, [str(exc)])]
            broken = True
        results.extend(got)
        for r in got:
            print(f"{r.name}: {r.figure} vs {r.baseline} -> {r.verdict}", file=sys.stderr, flush=True)
    print(format_table(results))
    if args.markdown:
        print()
        print(markdown_table(results))
    print(
        f"\n{sum(r.passed for r in results)}/{len(results)} targets met "
        f"({'quick' if args.quick else 'full'} run, {time.perf_counter() - t0:.0f} s)"
    )
    if broken:
        return 2
    return 0 if all(r.passed for r in results) else 1


if __name__ == "__main__":
    sys.exit(main())
