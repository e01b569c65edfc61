"""The firmware's "at position" is ``|target - ticks| < 5`` encoder ticks, not ``<= 5`` (issue 19 §1;
docs/protocols.md §2, STEPFOC firmware src/motor_control.cpp ``Gripper_mode``, ``POSITION_TOLERANCE``).

Raw frames on a python-can ``virtual`` bus, built with the codec (no client classes). The simulator's clock
is stepped by the test, so the one control tick (160 us) that separates a new command from the latch reset
and the few milliseconds a 5-tick motion lasts are exact whatever the machine's load. The gripper is given
about 11 ticks per mm, so neighbouring setpoint bytes lie 4 or 5 encoder ticks apart and both distances can
be commanded."""

from __future__ import annotations

from collections.abc import Iterator

import can
import pytest

from grippers.drivers.stepfoc.can_protocol import (
    Cmd,
    Detection,
    GripperCommand,
    decode_frame,
    encode_frame,
)
from grippers.drivers.stepfoc.sim import MsgModel, serve_can
from grippers.drivers.stepfoc.sim.can_server import CanSimServer

from ..rawmodel import SteppedClock

NODE = 0  # a virtual channel of its own: no other test sees these frames
TICKS_PER_MM = 11.0  # 105 mm of travel: 1155 ticks over 255 setpoint steps, 4 or 5 ticks a step
REPLY_S = 5.0  # wall seconds a reply may take on a busy machine (it comes at once when nothing is wrong)


class Raw:
    """One raw bus on the simulator's channel and the stepped clock."""

    def __init__(self, bus: can.BusABC, clock: SteppedClock) -> None:
        self.bus = bus
        self.clock = clock

    def ask(self, frame: tuple[int, bytes, bool], command: Cmd) -> can.Message:
        arbitration_id, data, remote = frame
        self.bus.send(
            can.Message(
                arbitration_id=arbitration_id, data=data, is_remote_frame=remote, is_extended_id=False
            )
        )
        while True:
            msg = self.bus.recv(timeout=REPLY_S)
            assert msg is not None, f"no reply to command {command.name}"
            if decode_frame(msg.arbitration_id, msg.data, msg.is_remote_frame).command == command:
                return msg

    def poll(self, after: float = 0.0) -> tuple[int, Detection]:
        """(position byte, detection) of the 60 reply to an empty 61 sent ``after`` simulated seconds on."""
        self.clock.t += after
        reply = self.ask(encode_frame(NODE, Cmd.GRIPPER_COMMAND), Cmd.GRIPPER_STATUS)
        status = decode_frame(reply.arbitration_id, reply.data).value
        return status.position, status.detection

    def ticks(self) -> int:
        """The encoder position (remote request 28)."""
        reply = self.ask(encode_frame(NODE, Cmd.ENCODER, remote=True), Cmd.ENCODER)
        return int(decode_frame(reply.arbitration_id, reply.data).value.position)

    def command(self, position: int, speed: int = 255, current_ma: int = 600) -> Detection:
        """A 5-byte 61 at the present simulated time; returns once the node answered it (its 60 reply), so
        the node has taken it before the test moves the clock."""
        value = GripperCommand(position, speed, current_ma, activate=True, action=True, estop=False)
        reply = self.ask(encode_frame(NODE, Cmd.GRIPPER_COMMAND, value), Cmd.GRIPPER_STATUS)
        return decode_frame(reply.arbitration_id, reply.data).value.detection

    def calibrate(self) -> None:
        """A 62 (no answer), then an encoder request answered after it: the node has taken the 62."""
        arbitration_id, data, _ = encode_frame(NODE, Cmd.GRIPPER_CALIBRATE)
        self.bus.send(can.Message(arbitration_id=arbitration_id, data=data, is_extended_id=False))
        self.ticks()


def c_map(x: int, out_min: int, out_max: int) -> int:
    """Arduino ``map(x, 0, 255, out_min, out_max)`` with C's truncating division."""
    product = x * (out_max - out_min)
    quotient = abs(product) // 255
    return out_min + (quotient if product >= 0 else -quotient)


@pytest.fixture
def raw(channel: str) -> Iterator[tuple[Raw, CanSimServer]]:
    clock = SteppedClock()
    model = MsgModel(node=NODE, ticks_per_mm=TICKS_PER_MM, current_noise=False)
    server = serve_can(model, f"can://virtual/{channel}", clock=clock)
    bus = can.Bus(interface="virtual", channel=channel)
    try:
        yield Raw(bus, clock), server
    finally:
        bus.shutdown()
        server.close()


def test_detection_3_within_4_ticks_and_not_at_5(raw: tuple[Raw, CanSimServer]) -> None:
    r, server = raw
    r.calibrate()
    r.poll(after=5.0)  # 1155 ticks each way at 5166 ticks/s, a pause and the current ramps: ~0.6 s
    with server.lock:
        assert server.model.calibrated and not server.model.calibrating
        open_ticks, closed_ticks = server.model.open_position, server.model.closed_position
    targets = [c_map(x, open_ticks, closed_ticks) for x in range(256)]
    # a setpoint whose lower neighbour is 5 ticks away and whose upper neighbour is 4 ticks away
    x = next(
        x for x in range(1, 255) if targets[x - 1] - targets[x] == 5 and targets[x] - targets[x + 1] == 4
    )

    r.command(x)
    r.poll(after=1.0)
    assert r.ticks() == targets[x]
    assert r.poll(after=0.001)[1] is Detection.AT_POSITION

    r.command(x + 1)  # 4 ticks from where the jaws are: at position at once
    assert r.poll(after=0.001)[1] is Detection.AT_POSITION  # after the control tick that reset the latch
    assert r.poll(after=1.0)[1] is Detection.AT_POSITION

    r.command(x - 1, speed=0)  # 5 ticks away: not at position; at ~500 ticks/s the 5 ticks take 10 ms
    assert r.poll(after=0.001)[1] is Detection.MOVING  # six control ticks on: the latch was reset, not set
    assert r.poll(after=1.0)[1] is Detection.AT_POSITION and r.ticks() == targets[x - 1]
