"""Target 12 (issue 20 §2): ``await g.state()`` against the threaded ``g.state()`` of the same gripper.

Both faces drive one gripper, so the device, the transport and the backend are shared and the ratio is the
cost of the asyncio face alone. Batches of each alternate (drift on a shared machine hits both alike); the
figure is the median latency of each. WSG over loopback TCP to a simulator in a child process; MSG over a
python-can ``virtual`` bus to an in-process simulator.
"""

from __future__ import annotations

import asyncio
import time
from typing import Any

from benchmarks.common import Result, median, us
from benchmarks.simproc import WsgSimProcess

RATIO_LIMIT = 1.15


def _compare(url: str, rounds: int, batch: int) -> tuple[float, float]:
    import grippers
    from grippers.aio import AsyncGripper, _Workers

    sync_lat: list[float] = []
    async_lat: list[float] = []
    g = grippers.open(url)

    async def main() -> None:
        ag = AsyncGripper(g, _Workers(g.name))
        try:
            for _ in range(20):  # warm up both paths
                g.state()
                await ag.state()
            for _ in range(rounds):
                for _ in range(batch):
                    t0 = time.perf_counter()
                    g.state()
                    sync_lat.append(time.perf_counter() - t0)
                for _ in range(batch):
                    t0 = time.perf_counter()
                    await ag.state()
                    async_lat.append(time.perf_counter() - t0)
        finally:
            await ag.close()

    try:
        asyncio.run(main())
    finally:
        g.close()
    return median(sync_lat), median(async_lat)


def run(quick: bool) -> list[Result]:
    rounds, batch = (5, 40) if quick else (20, 100)
    results = []
    cases: list[tuple[str, Any]] = [("WSG over TCP", None), ("MSG over CAN", "sim://msg-150")]
    for label, url in cases:
        if url is None:
            with WsgSimProcess() as sim:
                threaded, awaited = _compare(sim.url, rounds, batch)
        else:
            threaded, awaited = _compare(url, rounds, batch)
        ratio = awaited / threaded
        results.append(
            Result(
                f"13 aio state() {label}",
                us(awaited),
                us(threaded) + " (threaded g.state())",
                f"{ratio:.2f}x",
                f"<= {RATIO_LIMIT}x threaded",
                ratio <= RATIO_LIMIT,
                [f"{rounds * batch} calls of each, alternating batches of {batch}; one gripper, both faces"],
            )
        )
    return results
