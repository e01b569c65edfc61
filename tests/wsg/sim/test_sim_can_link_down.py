"""The WSG's CAN simulator keeps serving when its interface goes down between two reads.

A busy CI run (N4, the vcan suite's `test_wsg_reconnects_after_down_and_up`) ended the simulator's thread:
its first read of a wake-up was guarded against "Network is down", the reads that drain the queue after it
were not, and `ip link set vcan1 down` landed between them. A gripper on the wire does not notice its host's
interface; the simulated one must not die of it. Here the bus's interface goes down exactly there:
python-can's own ``virtual`` bus, whose read after the first frame of a request fails once with ENETDOWN, as
SocketCAN's does.
"""

from __future__ import annotations

import errno
import time
from typing import Any

import can
from can.interfaces.virtual import VirtualBus

import grippers
from grippers.drivers.wsg.sim import WsgModel
from grippers.drivers.wsg.sim.transports import CanSimServer


class DownOnceAfterAFrame(VirtualBus):
    """A virtual bus whose next read after the first frame it delivers once ``armed`` fails once, as a downed
    interface's."""

    def __init__(self, *args: Any, **kwargs: Any) -> None:
        super().__init__(*args, **kwargs)
        self.armed = self.delivered = self.failed = False

    def _recv_internal(self, timeout: float | None) -> tuple[can.Message | None, bool]:
        if self.delivered and not self.failed:
            self.failed = True
            raise can.CanOperationError("Network is down", error_code=errno.ENETDOWN)
        msg, filtered = super()._recv_internal(timeout)
        self.delivered = self.delivered or (self.armed and msg is not None)
        return msg, filtered


def test_the_simulator_survives_its_interface_going_down_between_two_reads() -> None:
    channel = f"wsg-down-{time.monotonic_ns()}"
    bus = DownOnceAfterAFrame(channel=channel)
    sim = CanSimServer(WsgModel(), interface="virtual", channel=channel, bus=bus, time_scale=50.0)
    try:
        with grippers.open(sim.url, timeout=0.5) as g:
            bus.armed = True
            try:
                g.state()  # the request during which the read failed may be lost, as on a downed wire
            except grippers.GripperTimeout:
                pass
            assert bus.failed
            assert g.state().width >= 0  # the simulator's thread is still serving
    finally:
        sim.close()
        bus.shutdown()
