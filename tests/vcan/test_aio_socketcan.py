"""The asyncio face on a real SocketCAN interface: the event loop reads the socket itself (``add_reader``,
drivers/stepfoc/can_reader.py) while the face is open and its loop runs; the reader thread only watches.
Node id 8 (no other test in this folder uses it).
"""

from __future__ import annotations

import asyncio
import dataclasses
import threading

import pytest

import grippers.aio
from grippers.drivers.stepfoc.sim import MsgModel, serve_can

pytestmark = pytest.mark.vcan
NODE = 8


def readers(vcan: str) -> list[threading.Thread]:
    return [t for t in threading.enumerate() if t.name == f"stepfoc-can stepfoc+can://socketcan/{vcan}"]


def test_the_loop_reads_socketcan_and_the_gripper_works_on_every_face(vcan: str) -> None:
    async def main() -> None:
        url = f"stepfoc+can://socketcan/{vcan}?node={NODE}&profile=msg-150"
        async with grippers.aio.open(url, timeout=2.0) as g:
            reader = g.sync.driver.bus._reader
            for _ in range(200):  # the reader thread hands over within its poll period (50 ms)
                if reader.loop_reads:
                    break
                await asyncio.sleep(0.01)
            assert reader.loop_reads
            await g.home()  # a motion: its blocking calls run on workers, their replies read by the loop
            moved = await g.move(0.05)
            native = await g.state()
            threaded = g.sync.state()  # blocking on the loop's own thread: it reads the socket itself
            assert abs(moved.width - 0.05) < 0.002
            assert dataclasses.replace(native, timestamp=0.0, current=None) == dataclasses.replace(
                threaded, timestamp=0.0, current=None
            )
            assert reader.loop_reads
        assert not readers(vcan)  # closed: the bus and its reader are gone

    with serve_can([MsgModel(node=NODE)], f"can://socketcan/{vcan}", time_scale=50.0):
        asyncio.run(asyncio.wait_for(main(), 60))
