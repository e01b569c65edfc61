"""The MSG simulator behaves as the STEPFOC firmware does (issue 12 §1; docs/protocols.md §2 "Firmware
behaviour a client must survive"). Driven by raw frames: identifiers and data bytes built by hand, no client
code."""

from __future__ import annotations

import struct

import can
import pytest

from grippers.drivers.stepfoc.sim import MsgModel, serve_can

from ..rawmodel import RawModel, cmd61, ident

NODE = 0
ESTOP, CLEAR, IDLE, WATCHDOG, ERROR_STATE, CMD_61, STATUS_60, CALIBRATE = 0, 1, 12, 15, 26, 61, 60, 62
ACTIVATE, ACTION, ESTOP_BIT = 0x80, 0x40, 0x20  # 61 flags (docs/protocols.md §2)
F_ESTOP, F_CALIBRATED = 0x02, 0x01  # 60 flags


class Raw(RawModel):
    def __init__(self, model: MsgModel) -> None:
        super().__init__(model, dt=0.01, step=0.02)

    def poll(self) -> tuple[int, int, int, int, bool]:
        return self.status()

    def error_state(self) -> tuple[int, int, bool]:
        (reply,) = self.send(ERROR_STATE, remote=True)
        return reply.data[0], reply.data[1], bool(reply.arbitration_id & 1)


def calibrated_at_rest() -> Raw:
    r = Raw(MsgModel(node=NODE))
    r.send(CALIBRATE)
    r.run(30.0)
    assert r.poll()[2] & F_CALIBRATED
    return r


def test_recalibration_keeps_the_calibrated_bit_and_freezes_detection() -> None:
    r = calibrated_at_rest()
    r.send(CMD_61, cmd61(128))
    r.run(5.0)
    position, _, flags, detection, _ = r.poll()
    assert detection == 3 and flags & ACTION and flags & ACTIVATE
    r.send(CALIBRATE)
    seen_positions = []
    for _ in range(200):  # the whole calibration, polled with empty 61s (which do not abort it)
        r.run(0.1)
        position, _, flags, detection, _ = r.poll()
        seen_positions.append(position)
        assert flags & F_CALIBRATED  # never cleared while it runs: no "calibrating" flag exists
        assert detection == 3  # frozen at the last value
        if not r.m.calibrating:
            break
    assert min(seen_positions) == 0 and seen_positions[-1] == 255
    # the end only idles the driver: activate, action and detection keep what the last 61 set
    _, current, flags, detection, _ = r.poll()
    # idle: no drive current, only the offset and noise of the reading (Get_current_mA)
    assert flags & ACTIVATE and flags & ACTION and detection == 3 and abs(current) < 80
    r.run(5.0)
    assert r.poll()[0] == 255  # idle: nothing moves although the stored 61 says "go to 128"


def test_last_61_survives_calibration_and_keeps_the_at_position_latch() -> None:
    r = calibrated_at_rest()
    r.send(CMD_61, cmd61(20, speed=10))
    r.run(60.0)
    assert r.poll()[3] == 3
    r.send(CALIBRATE)
    r.run(30.0)
    assert not r.m.calibrating and r.poll()[0] == 255
    r.send(CMD_61, cmd61(20, speed=10))  # byte for byte the one before the calibration
    r.run(0.01)
    position, _, _, detection, _ = r.poll()
    assert detection == 3 and position > 200  # "at position" at once, while the jaws are still closed
    # a command that differs in one byte resets the latch: detection 0 until it really arrives
    r.send(CMD_61, cmd61(20, speed=10, current=799))
    r.run(0.01)
    position, _, _, detection, _ = r.poll()
    assert detection == 0 and position > 100


def test_command_0_sets_only_the_drivers_estop_error() -> None:
    r = calibrated_at_rest()
    r.send(CMD_61, cmd61(0, speed=5))
    r.run(0.5)
    assert r.send(ESTOP) == []
    r.run(0.1)
    position, _, flags, _, error_bit = r.poll()
    assert error_bit and not flags & F_ESTOP  # the identifier's error bit; the 60 frame's flag stays 0
    byte0, _, err = r.error_state()
    assert err and byte0 & 0x80 and byte0 & 0x01  # frame 26: error and estop (its last bit)
    r.run(2.0)
    assert r.poll()[0] == position  # stopped


def test_61_estop_sets_the_60_flag_but_not_frame_26_estop() -> None:
    r = calibrated_at_rest()
    r.send(CMD_61, cmd61(0, flags=ACTIVATE | ACTION | ESTOP_BIT))
    r.run(0.1)
    _, _, flags, _, error_bit = r.poll()
    assert flags & F_ESTOP and error_bit
    byte0, _, _ = r.error_state()
    assert byte0 & 0x80 and not byte0 & 0x01  # controller.Error only; ESTOP_error is command 0's


def test_command_1_clears_every_error_and_idles_until_a_new_61() -> None:
    r = calibrated_at_rest()
    r.send(CMD_61, cmd61(0, speed=5))
    r.run(0.5)
    r.send(ESTOP)
    r.run(0.1)
    stopped = r.poll()[0]
    assert r.send(CLEAR) == []
    r.run(3.0)
    position, _, flags, _, error_bit = r.poll()
    assert not error_bit and position == stopped  # cleared, and nothing moves: the driver is idle
    assert flags & ACTION  # although the stored 61 still says "go"
    r.send(CMD_61, cmd61(0, speed=6))  # a new 5-byte 61 starts it again
    r.run(3.0)
    assert r.poll()[0] < stopped


def test_watchdog_ignores_its_action_byte() -> None:
    for action in (0, 1, 2):  # idle, hold, brake as the vendor library sends them: all the same
        r = calibrated_at_rest()
        r.send(CMD_61, cmd61(0, speed=5))
        r.send(WATCHDOG, struct.pack(">IB", 200, action))
        r.run(1.0)
        r.t += 0.01
        r.m.advance(r.t)
        assert r.m.timeout_error
        (reply,) = r.m.handle_frame(ident(CMD_61), b"", False, r.t)
        position, _, flags, _ = *struct.unpack(">BhB", reply.data), None
        assert flags & 0x04 and reply.arbitration_id & 1  # the 60 frame's timeout error and the error bit
        r.run(2.0)
        assert r.m.status(r.t).position == position  # idle, whatever the action byte said


def test_frame_26_byte_1_is_the_drivers_own_state() -> None:
    r = Raw(MsgModel(node=NODE))
    _, byte1, _ = r.error_state()
    assert byte1 & 0x80 and not byte1 & 0x40  # FOC calibration set (factory), driver not "activated"
    r.send(CALIBRATE)
    r.run(30.0)
    r.send(CMD_61, cmd61(100))  # the gripper is calibrated and activated now ...
    r.run(1.0)
    assert r.poll()[2] & (ACTIVATE | F_CALIBRATED) == ACTIVATE | F_CALIBRATED
    _, byte1_after, _ = r.error_state()
    assert byte1_after == byte1  # ... frame 26 does not show the gripper's bits


def test_a_61_during_calibration_aborts_it_even_when_identical() -> None:
    r = calibrated_at_rest()
    r.send(CMD_61, cmd61(100))
    r.run(3.0)
    r.send(CALIBRATE)
    r.run(0.2)
    assert r.m.calibrating
    r.send(CMD_61, cmd61(100))  # "same command": the mode still changes to gripper
    assert not r.m.calibrating


@pytest.mark.parametrize(
    ("arbitration_id", "extended"),
    [(0x800, False), (0xFFFF, False), (ident(CMD_61), True), (ident(ERROR_STATE) | 1 << 20, True)],
)
def test_can_sim_ignores_ids_invalid_for_the_frame_format(arbitration_id: int, extended: bool) -> None:
    channel = f"fw-ids-{arbitration_id:x}-{extended}"
    with serve_can([MsgModel(node=NODE)], f"can://virtual/{channel}", time_scale=50.0) as server:
        bus = can.Bus(interface="virtual", channel=channel)
        try:
            bus.send(
                can.Message(
                    arbitration_id=arbitration_id,
                    data=b"",
                    is_extended_id=extended,
                    is_remote_frame=arbitration_id >> 1 & 0x3F == ERROR_STATE,
                )
            )
            assert bus.recv(timeout=0.15) is None  # no answer to a frame of another format
            bus.send(can.Message(arbitration_id=ident(CMD_61), data=b"", is_extended_id=False))
            reply = bus.recv(timeout=1.0)
            assert reply is not None and reply.arbitration_id == ident(STATUS_60) and not reply.is_extended_id
        finally:
            bus.shutdown()
        assert server.error is None


def test_can_sim_refuses_a_node_whose_identifiers_do_not_fit_11_bits() -> None:
    model = MsgModel(node=3)
    model.node = 16  # 16 << 7 does not fit a standard identifier
    with pytest.raises(ValueError, match="11-bit"):
        serve_can([model], "can://virtual/fw-bad-node")
