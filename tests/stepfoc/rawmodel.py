"""Helpers of the firmware tests that drive the MSG simulator's model with raw frames at explicit SIMULATED
times: identifiers and data bytes built by hand, no client code, so the tests check the simulator against the
firmware and not against our own codec; and every window (a control tick, a poll period) is exact whatever the
machine's load."""

from __future__ import annotations

import struct

from grippers.drivers.simkit import SimClock
from grippers.drivers.stepfoc.sim import MsgModel

CMD_61, STATUS_60 = 61, 60
ACTIVATE, ACTION = 0x80, 0x40  # 61 flags (docs/protocols.md §2)


def ident(command: int, node: int = 0) -> int:
    return node << 7 | command << 1


def cmd61(position: int, speed: int = 255, current: int = 800, flags: int = ACTIVATE | ACTION) -> bytes:
    return struct.pack(">BBhB", position, speed, current, flags)


class RawModel:
    """A model fed raw frames at explicit simulated times; replies are read as raw bytes.

    ``dt``: the default simulated time between two frames; ``step``: the default tick of :meth:`run`."""

    def __init__(self, model: MsgModel, *, dt: float, step: float) -> None:
        self.m = model
        self.t = 0.0
        self.dt = dt
        self.step = step

    def send(self, command: int, data: bytes = b"", *, remote: bool = False, dt: float | None = None) -> list:
        self.t += self.dt if dt is None else dt
        return self.m.handle_frame(ident(command), data, remote, self.t)

    def run(self, seconds: float, step: float | None = None) -> None:
        tick = self.step if step is None else step
        end = self.t + seconds
        while self.t < end:
            self.t += tick
            self.m.advance(self.t)

    def status(self, dt: float | None = None) -> tuple[int, int, int, int, bool]:
        """(position, current, flags, detection, error bit) from the 60 reply to an empty 61."""
        (reply,) = self.send(CMD_61, dt=dt)
        assert reply.arbitration_id >> 1 & 0x3F == STATUS_60
        position, current, flags = struct.unpack(">BhB", reply.data)
        detection = (1 if flags & 0x20 else 0) | (2 if flags & 0x10 else 0)
        return position, current, flags, detection, bool(reply.arbitration_id & 1)


class SteppedClock(SimClock):
    """Simulated time that moves only when the test says so (``t``): a period under test is then exact."""

    def __init__(self, start: float = 0.0) -> None:
        super().__init__(1.0, start=start)
        self.t = start

    def now(self) -> float:
        return self.t
