"""The pure MSG device model, driven with simulated time (no transport): docs/protocols.md §2 behaviour."""

from __future__ import annotations

import pytest

from grippers.drivers.stepfoc.can_protocol import (
    CanFrame,
    Cmd,
    Detection,
    GripperCommand,
    Watchdog,
    WatchdogAction,
    decode_frame,
    encode_command,
    encode_frame,
    pack_id,
)
from grippers.drivers.stepfoc.sim.model import MsgModel, Phase


def go(position: int, speed: int = 255, current: int = 800, *, estop: bool = False) -> GripperCommand:
    return GripperCommand(position, speed, current, activate=True, action=True, estop=estop)


def calibrated(**kw: object) -> MsgModel:
    m = MsgModel(**kw)  # type: ignore[arg-type]
    m.start_calibration(0.0)
    m.advance(60.0)
    assert m.calibrated
    return m


def run_until_still(m: MsgModel, t: float, step: float = 0.05, limit: float = 120.0) -> float:
    while t < limit:
        t += step
        m.advance(t)
        if m.phase not in (Phase.MOVING, Phase.STARTING):
            return t
    raise AssertionError("never stopped")


def test_starts_uncalibrated_and_does_not_move() -> None:
    m = MsgModel()
    m.advance(0.0)
    # STEPFOC common.h: power-up detection 3; the stored stops are 10329 (open) and -229 (closed) until a
    # calibration, so the encoder's 0 reads as map(0, 10329, -229, 0, 255) = 249
    st = m.status(0.0)
    assert not m.calibrated and st.position == 249 and st.detection is Detection.AT_POSITION
    ticks = m.ticks
    assert m.on_command(go(200), 1.0)
    m.advance(5.0)
    assert m.ticks == ticks and m.phase is not Phase.MOVING


def test_calibration_opens_pauses_closes_and_ends_idle_at_255() -> None:
    m = MsgModel(travel_mm=105.0, start_mm=50.0)
    m.start_calibration(0.0)
    m.advance(0.5)
    assert m.phase is Phase.CAL_OPEN and m.current_ma > 0  # opening: positive current
    assert m.status(0.5).detection is Detection.AT_POSITION  # frozen at its power-up value
    opened_at = (105.0 - 50.0) * m.ticks_per_mm / m.calibration_speed
    m.advance(opened_at + 0.065)  # ~56 ms of current ramp at the stop, then the 16 ms pause
    assert m.phase is Phase.CAL_PAUSE and m.opening_mm == pytest.approx(105.0)
    m.advance(opened_at + m.calibration_pause_s + 0.5)
    assert m.phase is Phase.CAL_CLOSE and m.current_ma < 0  # closing: negative current
    assert not m.calibrated
    m.advance(60.0)
    st = m.status(60.0)
    assert st.calibrated and st.position == 255 and not st.action and m.phase is Phase.IDLE
    assert m.opening_mm == pytest.approx(0.0)
    assert m.open_position - m.closed_position == round(105.0 * m.ticks_per_mm)  # ticks grow towards open


def test_calibration_current_is_limited() -> None:
    m = MsgModel(moving_current_ma=900, current_noise=False)
    m.start_calibration(0.0)
    m.advance(0.2)
    assert abs(m.current_ma) <= 600


def test_five_byte_command_aborts_calibration_but_poll_does_not() -> None:
    m = MsgModel()
    m.start_calibration(0.0)
    poll = m.handle_frame(pack_id(0, Cmd.GRIPPER_COMMAND), b"", False, 1.0)
    assert len(poll) == 1 and m.calibrating
    m.handle_frame(pack_id(0, Cmd.GRIPPER_COMMAND), encode_command(go(10)), False, 1.5)
    assert not m.calibrating
    m.advance(60.0)
    assert not m.calibrated


def test_moves_only_when_activated_and_action() -> None:
    m = calibrated()
    start = m.ticks
    m.on_command(GripperCommand(0, 255, 800, activate=True, action=False, estop=False), 61.0)
    m.advance(70.0)
    assert m.ticks == start
    m.on_command(GripperCommand(0, 255, 800, activate=False, action=True, estop=False), 71.0)
    m.advance(80.0)
    assert m.ticks == start
    m.on_command(go(0), 81.0)
    m.advance(90.0)
    assert m.status(90.0).position == 0 and m.status(90.0).detection is Detection.AT_POSITION


def test_speed_map_sets_travel_time() -> None:
    slow, fast = calibrated(), calibrated()
    slow.on_command(go(0, speed=0), 60.0)
    fast.on_command(go(0, speed=255), 60.0)
    t_slow = run_until_still(slow, 60.0, step=0.5) - 60.0
    t_fast = run_until_still(fast, 60.0, step=0.01) - 60.0
    travel = 105.0 * 200.0
    assert t_slow == pytest.approx(travel / 500.0, abs=0.6)
    assert t_fast == pytest.approx(travel / 60000.0, abs=0.02)


def test_position_truncation_128_reads_127_with_detection_3() -> None:
    m = calibrated()
    m.on_command(go(128), 60.0)
    run_until_still(m, 60.0)
    st = m.status(100.0)
    assert st.position == 127 and st.detection is Detection.AT_POSITION


def test_immediate_reply_carries_previous_detection() -> None:
    m = calibrated()
    m.on_command(go(100), 60.0)
    t = run_until_still(m, 60.0)
    assert m.status(t).detection is Detection.AT_POSITION
    reply = m.handle_frame(pack_id(0, Cmd.GRIPPER_COMMAND), encode_command(go(200)), False, t + 1.0)
    assert decode_frame(reply[0].arbitration_id, reply[0].data).value.detection is Detection.AT_POSITION
    m.advance(t + 1.001)
    assert m.status(t + 1.001).detection is Detection.MOVING


def test_same_command_leaves_idle_without_a_new_motion() -> None:
    m = calibrated()
    assert m.on_command(go(100), 60.0)
    m.advance(60.01)
    m.idle(60.02)  # stops the motion; the stored command stays the same
    assert m.phase is Phase.IDLE
    # firmware: every 5-byte 61 sets gripper mode; "same command" only keeps the at-position latch
    assert not m.on_command(go(100), 60.03)
    assert m.phase in (Phase.STARTING, Phase.MOVING)
    assert m.on_command(go(100, speed=254), 60.04)
    assert m.phase in (Phase.STARTING, Phase.MOVING)


def test_part_closing_gives_detection_1_and_negative_current() -> None:
    m = calibrated(part_width_mm=40.0)
    m.on_command(go(0), 60.0)
    t = run_until_still(m, 60.0)
    m.on_command(go(255, current=600), t)
    t = run_until_still(m, t)
    m.advance(t + 0.1)
    st = m.status(t + 0.1)
    assert st.detection is Detection.CLOSING_OBJECT
    assert st.current_ma < -0.8 * 600  # above 80 % of the limit (docs/protocols.md §2)
    assert m.opening_mm == pytest.approx(40.0)


def test_inside_grip_part_gives_detection_2_and_positive_current() -> None:
    m = calibrated(part_width_mm=30.0, part_grip="inside")  # calibration ends closed, inside the ring
    m.on_command(go(0, current=500), 60.0)
    t = run_until_still(m, 60.0)
    m.advance(t + 0.1)
    st = m.status(t + 0.1)
    assert st.detection is Detection.OPENING_OBJECT and st.current_ma > 0.8 * 500
    assert m.opening_mm == pytest.approx(30.0)


def test_moving_reports_detection_0() -> None:
    m = calibrated()
    m.on_command(go(0, speed=10), 60.0)
    m.advance(61.0)
    assert m.status(61.0).detection is Detection.MOVING and m.status(61.0).current_ma > 0


def test_estop_flag_stops_motion_and_sets_error_bit() -> None:
    m = calibrated()
    m.on_command(go(0, speed=10), 60.0)
    m.advance(61.0)
    m.on_command(go(0, speed=10, estop=True), 61.5)
    ticks = m.ticks
    m.advance(65.0)
    assert m.ticks == ticks and m.status(65.0).estop_error and m.error_active
    (reply,) = m.handle_frame(pack_id(0, Cmd.GRIPPER_COMMAND), b"", False, 65.1)
    assert reply.arbitration_id & 1  # error bit in every identifier while an error is active


def test_clear_error_trap_error_returns_while_command_has_estop() -> None:
    m = calibrated()
    m.on_command(go(0, estop=True), 60.0)
    m.clear_error(61.0)
    assert not m.status(61.0).estop_error
    m.advance(61.1)
    assert m.status(61.1).estop_error  # back: the stored command still has estop
    m.on_command(go(0), 62.0)  # a 61 without estop does not clear the error by itself ...
    m.advance(62.05)
    assert m.status(62.05).estop_error
    m.clear_error(62.1)  # ... but after it the clear holds
    m.advance(63.0)
    assert not m.status(63.0).estop_error and not m.error_active


def test_estop_command_0_then_clear() -> None:
    m = calibrated()
    m.handle_frame(pack_id(0, Cmd.ESTOP), b"", False, 60.0)
    st = m.status(60.0)
    assert st.error_bit and not st.estop_error and m.error_state().estop  # the driver's, not the 60 flag
    m.handle_frame(pack_id(0, Cmd.CLEAR_ERROR), b"", False, 61.0)
    m.advance(61.5)
    assert not m.status(61.5).error_bit and not m.error_state().estop


def test_wrong_length_61_is_answered_with_60() -> None:
    m = calibrated()
    for n in (1, 2, 3, 4, 6, 7, 8):
        (reply,) = m.handle_frame(pack_id(0, Cmd.GRIPPER_COMMAND), bytes(n), False, 60.0 + n)
        assert decode_frame(reply.arbitration_id, reply.data).command == Cmd.GRIPPER_STATUS
    assert m.phase is Phase.IDLE  # and nothing moved


def test_frames_for_other_nodes_and_replies_are_ignored() -> None:
    m = MsgModel(node=3)
    assert m.handle_frame(pack_id(4, Cmd.GRIPPER_COMMAND), b"", False, 0.0) == []
    assert m.handle_frame(pack_id(3, Cmd.GRIPPER_STATUS), bytes(4), False, 0.0) == []
    assert m.handle_frame(pack_id(3, Cmd.TEMPERATURE), b"\x00\x01", False, 0.0) == []  # data frame = a reply
    assert m.handle_frame(pack_id(3, Cmd.GRIPPER_CALIBRATE), b"", False, 0.0) == []
    assert m.calibrating
    assert len(m.handle_frame(pack_id(3, Cmd.GRIPPER_COMMAND), b"", False, 0.1)) == 1


@pytest.mark.parametrize(
    ("command", "value"),
    [(Cmd.PING, None), (Cmd.TEMPERATURE, 31), (Cmd.BUS_VOLTAGE, 24000), (Cmd.IQ, 0)],
)
def test_remote_requests_answered(command: Cmd, value: object) -> None:
    m = MsgModel(node=2, current_noise=False)
    (reply,) = m.handle_frame(pack_id(2, command), b"", True, 0.0)
    assert not reply.remote
    assert decode_frame(reply.arbitration_id, reply.data).value == value


def test_device_info_error_state_encoder() -> None:
    m = MsgModel(hardware_version=3, batch_date=7, software_version=15, serial=424242)
    (info,) = m.handle_frame(pack_id(0, Cmd.DEVICE_INFO), b"", True, 0.0)
    v = decode_frame(info.arbitration_id, info.data).value
    assert (v.hardware_version, v.batch_date, v.software_version, v.serial) == (3, 7, 15, 424242)
    m.emergency_stop(1.0)
    (es,) = m.handle_frame(pack_id(0, Cmd.ERROR_STATE), b"", True, 1.0)
    state = decode_frame(es.arbitration_id, es.data).value
    # byte 1 is the driver's own state: its factory FOC calibration, not the gripper's calibrated bit
    assert state.error and state.estop and state.calibrated and not m.calibrated and es.arbitration_id & 1
    (enc,) = m.handle_frame(pack_id(0, Cmd.ENCODER), b"", True, 1.0)
    assert decode_frame(enc.arbitration_id, enc.data).value.position == m.ticks


def test_heartbeat_when_configured() -> None:
    m = MsgModel(node=1)
    assert m.due_frames(10.0) == []
    m.handle_frame(*encode_frame(1, Cmd.HEARTBEAT_SETUP, 100)[:2], False, 10.0)
    assert m.due_frames(10.05) == []
    assert m.due_frames(10.11) == [CanFrame(pack_id(1, Cmd.HEARTBEAT), b"", False)]
    m.set_heartbeat(0, 11.0)
    assert m.due_frames(20.0) == []


def test_set_can_id_save_and_reset() -> None:
    m = calibrated(node=0)
    m.handle_frame(*encode_frame(0, Cmd.SET_CAN_ID, 9)[:2], False, 61.0)
    assert m.node == 9
    assert m.handle_frame(pack_id(0, Cmd.GRIPPER_COMMAND), b"", False, 61.1) == []
    m.handle_frame(pack_id(9, Cmd.RESET), b"", False, 62.0)
    assert m.node == 0 and not m.calibrated  # not saved: back to the old id; calibration lost
    m.handle_frame(*encode_frame(0, Cmd.SET_CAN_ID, 9)[:2], False, 63.0)
    m.handle_frame(pack_id(9, Cmd.SAVE_CONFIG), b"", False, 63.1)
    m.handle_frame(pack_id(9, Cmd.RESET), b"", False, 63.2)
    assert m.node == 9


def test_watchdog_raises_timeout_error() -> None:
    m = calibrated()
    m.handle_frame(pack_id(0, Cmd.GRIPPER_COMMAND), b"", False, 60.0)  # a poll feeds it
    m.set_watchdog(encode_and_decode_watchdog(200, WatchdogAction.IDLE), 60.0)
    m.advance(60.1)
    assert not m.status(60.1).timeout_error
    m.advance(60.5)
    assert m.status(60.5).timeout_error and m.error_active
    m.clear_error(61.0)
    assert not m.status(61.0).timeout_error


def encode_and_decode_watchdog(ms: int, action: WatchdogAction) -> Watchdog:
    frame = encode_frame(0, Cmd.WATCHDOG, Watchdog(ms, action))
    return decode_frame(frame.arbitration_id, frame.data).value


def test_idle_stops_motion() -> None:
    m = calibrated()
    m.on_command(go(0, speed=10), 60.0)
    m.advance(61.0)
    m.handle_frame(pack_id(0, Cmd.IDLE), b"", False, 61.0)
    ticks = m.ticks
    m.advance(70.0)
    assert m.ticks == ticks and m.action  # idle changes the driver mode only, not the gripper's bits


def test_uart_set_position_activates_and_moves() -> None:
    m = calibrated()
    m.set_speed(255, 60.0)
    m.set_current(500, 60.0)
    m.set_position(0, 60.0)
    assert m.activated and m.action
    run_until_still(m, 60.0)
    assert m.position == 0
