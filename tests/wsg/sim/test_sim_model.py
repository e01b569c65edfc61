"""The WSG device model by direct calls: every behaviour the manuals describe, in simulated time."""

from __future__ import annotations

import struct

import pytest
from hypothesis import given
from hypothesis import strategies as st

from grippers.drivers.wsg.commands import (
    Cmd,
    FingerFlags,
    FingerType,
    FirmwareVersion,
    GraspingState,
    SystemFlags,
    decode_reply,
)
from grippers.drivers.wsg.protocol import Packet, PacketParser, Status
from grippers.drivers.wsg.sim import WsgModel

S = Status
G = GraspingState
F = SystemFlags


def flags(d) -> SystemFlags:
    return d.one(Cmd.GET_SYSTEM_STATE).fields["state"]


def gstate(d) -> GraspingState:
    return d.one(Cmd.GET_GRASPING_STATE).fields["state"]


def width(d) -> float:
    return d.one(Cmd.GET_WIDTH).fields["width"]


def move(d, w: float, speed: float = 100.0, **flags_: bool):
    assert d.one(Cmd.PREPOSITION, width=w, speed=speed, **flags_).status == S.E_CMD_PENDING
    return d.until_done(Cmd.PREPOSITION)


def grip(d, w: float, speed: float = 100.0):
    assert d.one(Cmd.GRIP, width=w, speed=speed).status == S.E_CMD_PENDING
    return d.until_done(Cmd.GRIP)


# ---------------------------------------------------------------------------------------------- referencing


def test_motion_needs_homing_first(driver) -> None:
    assert driver.one(Cmd.PREPOSITION, width=10, speed=50).status == S.E_NOT_INITIALIZED
    assert driver.one(Cmd.GRIP, width=10, speed=50).status == S.E_NOT_INITIALIZED
    assert driver.one(Cmd.RELEASE, width=10, speed=50).status == S.E_NOT_INITIALIZED
    # §3.4.4: not referenced -> width 0
    assert width(driver) == 0.0
    assert not flags(driver) & F.SF_REFERENCED


@pytest.mark.parametrize(("direction", "end"), [(0, 110.0), (1, 110.0), (2, 0.0)])
def test_homing_goes_to_the_end_stop(driver, direction: int, end: float) -> None:
    first = driver.one(Cmd.HOMING, direction=direction)
    assert first.status == S.E_CMD_PENDING
    assert gstate(driver) == G.POSITIONING
    assert flags(driver) & F.SF_MOVING
    assert driver.until_done(Cmd.HOMING).status == S.E_SUCCESS
    assert width(driver) == pytest.approx(end)
    assert flags(driver) & F.SF_REFERENCED
    assert gstate(driver) == G.IDLE


def test_homing_rejects_bad_direction_and_length(driver) -> None:
    assert driver.one(Cmd.HOMING, direction=3).status == S.E_INVALID_PARAMETER
    assert driver.raw(Cmd.HOMING, b"\x00\x00")[0].status == S.E_CMD_FORMAT_ERROR


# ----------------------------------------------------------------------------------------------- motion


def test_preposition_moves_in_simulated_time(homed) -> None:
    d = homed
    assert d.one(Cmd.PREPOSITION, width=10.0, speed=100.0).status == S.E_CMD_PENDING
    d.advance(0.5)
    w = width(d)
    assert 10.0 < w < 110.0
    assert d.one(Cmd.GET_SPEED).fields["speed"] == pytest.approx(-100.0)  # cruising, closing
    assert flags(d) & F.SF_MOVING
    assert d.until_done(Cmd.PREPOSITION).status == S.E_SUCCESS
    assert width(d) == pytest.approx(10.0)
    assert d.one(Cmd.GET_SPEED).fields["speed"] == 0.0
    f = flags(d)
    assert f & F.SF_TARGET_POS_REACHED and not f & F.SF_MOVING


def test_trapezoid_duration_uses_speed_and_acceleration(homed) -> None:
    d = homed
    assert d.one(Cmd.SET_ACCELERATION, acceleration=500.0).ok
    start = d.now
    move(d, 10.0, speed=100.0, relative=False)
    # 100 mm at 100 mm/s with 500 mm/s²: 0.2 s up, 0.8 s cruise, 0.2 s down = 1.2 s (within a step)
    assert d.now - start == pytest.approx(1.2, abs=0.02)


def test_relative_preposition(homed) -> None:
    move(homed, 50.0)
    assert move(homed, -20.0, relative=True).ok
    assert width(homed) == pytest.approx(30.0)
    assert move(homed, 5.0, relative=True).ok
    assert width(homed) == pytest.approx(35.0)


def test_targets_and_speeds_are_clamped_to_the_limits(homed) -> None:
    d = homed
    assert move(d, 500.0, speed=1e6).ok
    assert width(d) == pytest.approx(110.0)
    start = d.now
    assert move(d, -50.0, speed=1e6).ok  # clamped to 0 mm at 420 mm/s
    assert width(d) == pytest.approx(0.0)
    assert d.now - start < 110.0 / 400.0 + 0.5
    assert d.one(Cmd.SET_ACCELERATION, acceleration=1e9).ok
    assert d.one(Cmd.GET_ACCELERATION).fields["acceleration"] == 5000.0
    assert d.one(Cmd.SET_ACCELERATION, acceleration=1.0).ok
    assert d.one(Cmd.GET_ACCELERATION).fields["acceleration"] == 100.0


def test_force_limit_clamped_and_overdrive(make_driver) -> None:
    d = make_driver(overdrive_force=120.0)
    assert d.one(Cmd.SET_FORCE_LIMIT, force=1000.0).ok
    assert d.one(Cmd.GET_FORCE_LIMIT).fields["force"] == 80.0
    assert d.one(Cmd.SET_FORCE_LIMIT, force=0.0).ok
    assert d.one(Cmd.GET_FORCE_LIMIT).fields["force"] == 5.0
    assert d.one(Cmd.OVERDRIVE, enable=True).ok
    assert flags(d) & F.SF_OVERDRIVE_MODE
    assert d.one(Cmd.SET_FORCE_LIMIT, force=1000.0).ok
    assert d.one(Cmd.GET_FORCE_LIMIT).fields["force"] == 120.0
    # §3.3.8: leaving overdrive reduces the limit to the nominal force
    assert d.one(Cmd.OVERDRIVE, enable=False).ok
    assert d.one(Cmd.GET_FORCE_LIMIT).fields["force"] == 80.0


def test_soft_limits(homed) -> None:
    d = homed
    assert d.one(Cmd.GET_SOFT_LIMITS).status == S.E_NOT_AVAILABLE
    assert d.one(Cmd.SET_SOFT_LIMITS, minus=10.0, plus=100.0).ok
    limits = d.one(Cmd.GET_SOFT_LIMITS).fields
    assert (limits["minus"], limits["plus"]) == (10.0, 100.0)
    assert d.one(Cmd.PREPOSITION, width=5.0, speed=50).status == S.E_RANGE_ERROR
    assert d.one(Cmd.PREPOSITION, width=-105.0, speed=50, relative=True).status == S.E_RANGE_ERROR
    assert d.one(Cmd.GRIP, width=105.0, speed=50).status == S.E_RANGE_ERROR
    assert d.one(Cmd.RELEASE, width=101.0, speed=50).status == S.E_RANGE_ERROR
    assert move(d, 10.0).ok
    assert flags(d) & F.SF_SOFT_LIMIT_MINUS
    assert d.one(Cmd.CLEAR_SOFT_LIMITS).ok
    assert d.one(Cmd.GET_SOFT_LIMITS).status == S.E_NOT_AVAILABLE
    assert not flags(d) & F.SF_SOFT_LIMIT_MINUS
    assert d.one(Cmd.PREPOSITION, width=5.0, speed=50).status == S.E_CMD_PENDING


def abort_a_motion_with(d, command: int, *, after: float) -> None:
    """A preposition to 0 at 50 mm/s, ``after`` simulated seconds, then ``command``, which aborts it."""
    assert d.one(Cmd.PREPOSITION, width=0.0, speed=50.0).pending
    d.advance(after)
    replies = d.call(command)
    assert [(r.command, r.status) for r in replies] == [
        (Cmd.PREPOSITION, S.E_CMD_ABORTED),
        (command, S.E_SUCCESS),
    ]


def test_stop_aborts_the_pending_motion(homed) -> None:
    d = homed
    abort_a_motion_with(d, Cmd.STOP, after=0.3)
    stopped_at = width(d)
    assert 0.0 < stopped_at < 110.0
    d.advance(1.0)
    assert width(d) == stopped_at
    assert flags(d) & F.SF_AXIS_STOPPED
    assert gstate(d) == G.IDLE
    # Appendix B: SF_AXIS_STOPPED is reset by the next motion command
    assert d.one(Cmd.PREPOSITION, width=50.0, speed=50.0).pending
    assert not flags(d) & F.SF_AXIS_STOPPED


def test_stop_takes_no_parameters(driver) -> None:
    assert driver.raw(Cmd.STOP, b"\x01")[0].status == S.E_NO_PARAM_EXPECTED


@pytest.mark.parametrize("second", [Cmd.HOMING, Cmd.PREPOSITION, Cmd.GRIP, Cmd.RELEASE])
def test_new_motion_while_one_is_pending_is_already_running(homed, second: int) -> None:
    d = homed
    assert d.one(Cmd.PREPOSITION, width=0.0, speed=20.0).pending
    fields = {} if second == Cmd.HOMING else {"width": 50.0, "speed": 50.0}
    assert d.one(second, **fields).status == S.E_ALREADY_RUNNING
    # the first motion goes on to its own end
    assert d.until_done(Cmd.PREPOSITION).ok
    assert width(d) == pytest.approx(0.0)


def test_fast_stop_and_acknowledge(homed) -> None:
    d = homed
    abort_a_motion_with(d, Cmd.FAST_STOP, after=0.2)
    assert flags(d) & F.SF_FAST_STOP
    assert gstate(d) == G.ERROR
    for cmd, fields in [
        (Cmd.HOMING, {}),
        (Cmd.PREPOSITION, {"width": 1, "speed": 9}),
        (Cmd.GRIP, {"width": 1, "speed": 9}),
        (Cmd.RELEASE, {"width": 1, "speed": 9}),
    ]:
        assert d.one(cmd, **fields).status == S.E_ACCESS_DENIED
    # state commands still work
    assert d.one(Cmd.GET_WIDTH).ok
    assert d.one(Cmd.ACK_FAST_STOP, key=b"ACK").status == S.E_CMD_FORMAT_ERROR
    assert d.raw(Cmd.ACK_FAST_STOP, b"ac")[0].status == S.E_CMD_FORMAT_ERROR
    assert flags(d) & F.SF_FAST_STOP
    assert d.one(Cmd.ACK_FAST_STOP, key=b"ack").ok
    assert not flags(d) & F.SF_FAST_STOP
    assert gstate(d) == G.ERROR  # §3.4.2: persists until the next movement command
    assert move(d, 30.0).ok
    assert gstate(d) == G.IDLE


def test_fast_stop_on_2x_has_no_error_grasping_state(make_driver) -> None:
    d = make_driver(firmware="2.2.0")
    assert d.one(Cmd.FAST_STOP).ok
    assert flags(d) & F.SF_FAST_STOP
    assert gstate(d) == G.IDLE  # 2.2.0 §3.4.2: 7 is reserved


def test_last_command_failure_flag(homed) -> None:
    d = homed
    assert d.one(Cmd.GET_SOFT_LIMITS).status == S.E_NOT_AVAILABLE
    assert flags(d) & F.SF_CMD_FAILURE  # the failing command was the last one before 40h
    assert not flags(d) & F.SF_CMD_FAILURE


# -------------------------------------------------------------------------------------------------- grip


def test_grip_holds_a_part_in_the_window(make_driver) -> None:
    d = make_driver(part_width_mm=50.0, clamping_travel_mm=5.0)
    d.home()
    assert d.one(Cmd.SET_FORCE_LIMIT, force=40.0).ok
    assert d.one(Cmd.GRIP, width=52.0, speed=100.0).pending
    d.advance(0.1)
    assert gstate(d) == G.GRIPPING
    assert d.until_done(Cmd.GRIP).status == S.E_SUCCESS
    assert gstate(d) == G.HOLDING
    assert width(d) == pytest.approx(50.0)
    assert d.one(Cmd.GET_FORCE).fields["force"] == 40.0
    stats = d.one(Cmd.GET_GRASPING_STATISTICS).fields
    assert (stats["total"], stats["no_part"], stats["lost_part"]) == (1, 0, 0)


@pytest.mark.parametrize(("part", "end"), [(None, 45.0), (40.0, 45.0), (60.0, 60.0)])
def test_grip_without_a_part_in_the_window_is_no_part(make_driver, part, end) -> None:
    d = make_driver(part_width_mm=part, clamping_travel_mm=5.0)
    d.home()
    # nominal 50 mm, clamping travel 5 mm: a part must be met between 45 and 55 mm
    assert grip(d, 50.0).status == S.E_CMD_FAILED
    assert gstate(d) == G.NO_PART
    assert width(d) == pytest.approx(end)
    assert d.one(Cmd.GET_FORCE).fields["force"] == 0.0
    stats = d.one(Cmd.GET_GRASPING_STATISTICS, reset=True).fields
    assert (stats["total"], stats["no_part"]) == (1, 1)
    stats = d.one(Cmd.GET_GRASPING_STATISTICS).fields
    assert (stats["total"], stats["no_part"], stats["lost_part"]) == (0, 0, 0)


def test_part_lost_while_holding(make_driver) -> None:
    d = make_driver(part_width_mm=30.0, clamping_travel_mm=4.0)
    d.home()
    assert grip(d, 30.0).ok
    d.model.remove_part(d.now)
    assert gstate(d) == G.PART_LOST
    d.advance(1.0)
    assert width(d) == pytest.approx(26.0)  # fell through the clamping travel
    assert d.one(Cmd.GET_FORCE).fields["force"] == 0.0
    assert d.one(Cmd.GET_GRASPING_STATISTICS).fields["lost_part"] == 1
    assert d.one(Cmd.RELEASE, width=80.0, speed=200.0).pending
    assert gstate(d) == G.RELEASING
    assert d.until_done(Cmd.RELEASE).ok
    assert gstate(d) == G.IDLE
    assert width(d) == pytest.approx(80.0)


def test_release_returns_to_idle(make_driver) -> None:
    d = make_driver(part_width_mm=30.0)
    d.home()
    assert grip(d, 30.0).ok
    assert d.one(Cmd.RELEASE, width=60.0, speed=100.0).pending
    assert d.until_done(Cmd.RELEASE).ok
    assert gstate(d) == G.IDLE
    assert d.one(Cmd.GET_FORCE).fields["force"] == 0.0
    assert width(d) == pytest.approx(60.0)


def test_regrip_same_direction_allowed_opposite_refused(make_driver) -> None:
    d = make_driver(part_width_mm=30.0, clamping_travel_mm=5.0)
    d.home()
    assert grip(d, 33.0).ok
    assert grip(d, 31.0).ok  # §3.2.6: re-grip in the same direction
    assert gstate(d) == G.HOLDING
    assert d.one(Cmd.GRIP, width=80.0, speed=50.0).status == S.E_CMD_FAILED


def test_stop_on_block_and_clamp_on_block(make_driver) -> None:
    d = make_driver(part_width_mm=30.0)
    d.home()
    assert move(d, 10.0, stop_on_block=True).status == S.E_AXIS_BLOCKED
    assert width(d) == pytest.approx(30.0)
    assert flags(d) & F.SF_BLOCKED_MINUS
    assert d.one(Cmd.GET_FORCE).fields["force"] == 0.0
    assert move(d, 60.0).ok
    assert not flags(d) & F.SF_BLOCKED_MINUS
    assert move(d, 10.0, stop_on_block=False).status == S.E_AXIS_BLOCKED
    assert d.one(Cmd.GET_FORCE).fields["force"] == 40.0  # 4.0.x §3.2.2: 50 % of the nominal force
    # §3.2.2: the blocking condition removed while clamping -> the fingers snap to the target
    d.model.remove_part(d.now)
    d.advance(1.0)
    assert width(d) == pytest.approx(10.0)


def test_clamp_on_block_uses_force_limit_on_2x(make_driver) -> None:
    d = make_driver(part_width_mm=30.0, firmware="2.2.0")
    d.home()
    assert d.one(Cmd.SET_FORCE_LIMIT, force=20.0).ok
    assert move(d, 10.0).status == S.E_AXIS_BLOCKED
    assert d.one(Cmd.GET_FORCE).fields["force"] == 20.0


def test_part_placed_in_the_way_of_a_motion(homed) -> None:
    d = homed
    assert d.one(Cmd.PREPOSITION, width=0.0, speed=50.0, stop_on_block=True).pending
    d.advance(0.1)
    d.model.place_part(60.0, d.now)
    assert d.until_done(Cmd.PREPOSITION).status == S.E_AXIS_BLOCKED
    assert width(d) == pytest.approx(60.0)


# ---------------------------------------------------------------------------------------- configuration


def test_tare(make_driver) -> None:
    assert make_driver().one(Cmd.TARE).status == S.E_NOT_AVAILABLE
    d = make_driver(force_fingers=True, part_width_mm=20.0)
    assert d.one(Cmd.TARE).ok
    assert flags(d) & F.SF_FORCECNTL_MODE
    d.home()
    assert grip(d, 20.0).ok
    assert d.one(Cmd.TARE).status == S.E_ACCESS_DENIED  # §3.3.9: not while HOLDING


def test_temperature_and_firmware_2x_unknown_commands(make_driver) -> None:
    d = make_driver(temperature_c=42.5)
    assert d.one(Cmd.GET_TEMPERATURE).fields["temperature"] == pytest.approx(42.5)
    old = make_driver(firmware="2.2.0")
    for cmd in (0x46, 0x60, 0x61, 0x62, 0x63, 0x70, 0x71, 0x72, 0x73):
        assert old.raw(cmd)[0].status == S.E_CMD_UNKNOWN
    assert old.one(Cmd.GET_SYSTEM_INFO).fields["firmware"] == FirmwareVersion(2, 2, 0)


def test_unknown_command_and_length_errors(driver) -> None:
    reply = driver.raw(0x90)[0]
    assert (reply.command, reply.status) == (0x90, S.E_CMD_UNKNOWN)
    assert driver.raw(Cmd.SET_ACCELERATION, b"\x00\x00\x16")[0].status == S.E_CMD_FORMAT_ERROR
    assert driver.raw(Cmd.GET_ACCELERATION, b"\x00")[0].status == S.E_NO_PARAM_EXPECTED
    assert driver.raw(Cmd.GRIP, bytes(7))[0].status == S.E_CMD_FORMAT_ERROR
    assert driver.raw(Cmd.LOOP, bytes(257))[0].status == S.E_CMD_FORMAT_ERROR


def test_loop_echoes_payload(driver) -> None:
    reply = driver.raw(Cmd.LOOP, b"\x01\xaa\xaa\xaa\x02")[0]
    assert reply.ok and reply.fields["data"] == b"\x01\xaa\xaa\xaa\x02"


def test_checksum_error_answered_under_its_id(driver, decode) -> None:
    replies = decode(driver.model.checksum_failed(0x21, 0.0))
    assert [(r.command, r.status) for r in replies] == [(0x21, S.E_CHECKSUM_ERROR)]


def test_device_tag(driver) -> None:
    assert driver.one(Cmd.GET_DEVICE_TAG).status == S.E_NOT_AVAILABLE
    assert driver.one(Cmd.SET_DEVICE_TAG, tag="cell 4 / left").ok
    assert driver.one(Cmd.GET_DEVICE_TAG).fields["tag"] == "cell 4 / left"
    assert driver.one(Cmd.SET_DEVICE_TAG, tag="x" * 64).ok
    assert driver.one(Cmd.SET_DEVICE_TAG, tag="x" * 65).status == S.E_OVERRUN
    assert driver.one(Cmd.SET_DEVICE_TAG, tag="bad\ttag").status == S.E_INVALID_PARAMETER
    assert driver.raw(Cmd.SET_DEVICE_TAG, b"caf\xe9")[0].status == S.E_INVALID_PARAMETER
    assert driver.one(Cmd.GET_DEVICE_TAG).fields["tag"] == "x" * 64


def test_system_info_and_limits_follow_parameters(make_driver) -> None:
    d = make_driver(
        device_type=6,
        serial=0xDEADBEEF,
        firmware="4.1.2-rc3",
        stroke_mm=140.0,
        min_speed=1.0,
        max_speed=300.0,
        min_accel=50.0,
        max_accel=2000.0,
        min_force=10.0,
        max_force=200.0,
        overdrive_force=250.0,
    )
    info = d.one(Cmd.GET_SYSTEM_INFO).fields
    assert (int(info["device_type"]), info["serial"], str(info["firmware"])) == (6, 0xDEADBEEF, "4.1.2-rc3")
    limits = d.one(Cmd.GET_SYSTEM_LIMITS).fields
    assert limits == {
        "stroke": 140.0,
        "min_speed": 1.0,
        "max_speed": 300.0,
        "min_acceleration": 50.0,
        "max_acceleration": 2000.0,
        "min_force": 10.0,
        "nominal_force": 200.0,
        "overdrive_force": 250.0,
    }


def test_finger_interface_generic_fingers(driver) -> None:
    d = driver
    info = d.one(0x60).fields
    assert (info["finger_type"], info["data_size"]) == (FingerType.GENERIC, 0)
    assert d.one(0x63).status == S.E_NOT_AVAILABLE
    assert d.one(0x61).fields["flags"] & FingerFlags.POWER_ON
    assert d.one(0x62, power=False).ok  # switching off is immediate
    assert not d.one(0x61).fields["flags"] & FingerFlags.POWER_ON
    assert d.one(0x62, power=True).pending
    assert d.advance(0.4) == []
    assert not d.one(0x61).fields["flags"] & FingerFlags.POWER_ON
    done = d.advance(0.2)
    assert [(r.command, r.status) for r in done] == [(0x62, S.E_SUCCESS)]
    assert d.one(0x61).fields["flags"] & FingerFlags.POWER_ON
    assert d.one(0x71).fields["flags"] & FingerFlags.POWER_ON  # finger 2 untouched


def test_finger_interface_force_fingers(make_driver) -> None:
    d = make_driver(force_fingers=True, part_width_mm=20.0, default_force=30.0)
    info = d.one(0x70).fields
    assert (info["finger_type"], info["data_size"]) == (FingerType.WSG_FMF, 4)
    assert d.one(0x72, power=False).status == S.E_ACCESS_DENIED  # predefined fingers cannot be switched
    d.home()
    assert grip(d, 20.0).ok
    data = d.one(0x73).fields["data"]
    assert struct.unpack("<f", data)[0] == pytest.approx(15.0)


# --------------------------------------------------------------------------------------------- auto updates


def test_auto_update_periodic(homed) -> None:
    d = homed
    first = d.one(Cmd.GET_WIDTH, auto_update=True, period_ms=50)
    assert first.ok and first.fields["width"] == pytest.approx(110.0)
    updates = [r for _ in range(20) for r in d.advance(0.01)]
    assert len(updates) == 4  # 200 ms at 50 ms
    assert all(r.command == Cmd.GET_WIDTH and r.ok for r in updates)
    assert d.one(Cmd.GET_WIDTH).ok  # auto update off again
    assert [r for _ in range(20) for r in d.advance(0.01)] == []


def test_auto_update_changes_only(homed) -> None:
    d = homed
    assert d.one(Cmd.GET_WIDTH, auto_update=True, changes_only=True, period_ms=20).ok
    assert [r for _ in range(10) for r in d.advance(0.01)] == []  # standing still: nothing
    assert d.one(Cmd.PREPOSITION, width=50.0, speed=100.0).pending
    updates = []
    for _ in range(100):
        updates += [r for r in d.advance(0.01) if r.command == Cmd.GET_WIDTH]
    widths = [r.fields["width"] for r in updates]
    assert len(widths) >= 10 and widths == sorted(widths, reverse=True)
    assert widths[-1] == pytest.approx(50.0)
    assert [r for _ in range(10) for r in d.advance(0.01) if r.command == Cmd.GET_WIDTH] == []


def test_auto_update_minimum_period_and_state_flow_during_motion(homed) -> None:
    d = homed
    # Issue 12 §4: below the manual's 10 ms minimum (4.0.x §3.4.1) the request is refused with the only
    # refusal the section lists, and no subscription starts; a plain query (period 0, updates off) is fine.
    for period in (0, 1, 9):
        refused = d.one(Cmd.GET_GRASPING_STATE, auto_update=True, period_ms=period)
        assert refused.status == S.E_CMD_FORMAT_ERROR
    assert [r for r in d.advance(0.05) if r.command == Cmd.GET_GRASPING_STATE] == []
    assert d.one(Cmd.GET_GRASPING_STATE).ok
    assert d.one(Cmd.GET_GRASPING_STATE, auto_update=True, period_ms=10).ok
    assert d.one(Cmd.PREPOSITION, width=0.0, speed=50.0).pending
    updates = [r for r in d.advance(0.1) if r.command == Cmd.GET_GRASPING_STATE]
    assert len(updates) == 1  # one step of 100 ms: coalesced, never more than one per period
    many = [r for _ in range(10) for r in d.advance(0.005) if r.command == Cmd.GET_GRASPING_STATE]
    assert len(many) == 5  # 50 ms at the 10 ms minimum period
    assert all(r.fields["state"] == G.POSITIONING for r in many)
    assert d.one(Cmd.GET_SYSTEM_STATE).ok  # state commands answered while the motion is pending


# ---------------------------------------------------------------------------------------------- connections


def test_disconnect_announcement_then_access_denied(homed) -> None:
    d = homed
    other = d.model.connect()
    assert d.one(Cmd.PREPOSITION, width=0.0, speed=50.0).pending
    replies = d.call(Cmd.DISCONNECT)
    assert [(r.command, r.status) for r in replies] == [
        (Cmd.PREPOSITION, S.E_CMD_ABORTED),
        (Cmd.DISCONNECT, S.E_SUCCESS),
    ]
    for cmd in (Cmd.GET_WIDTH, Cmd.LOOP, Cmd.DISCONNECT, 0x90):
        assert d.raw(cmd)[0].status == S.E_ACCESS_DENIED
    d.model.connection_lost(d.now, 0)
    assert not flags_on(d, other) & F.SF_FAST_STOP


def flags_on(d, conn: int) -> SystemFlags:
    return d.one(Cmd.GET_SYSTEM_STATE, conn=conn).fields["state"]


def test_unannounced_drop_enters_fast_stop(homed) -> None:
    d = homed
    client = d.model.connect()
    observer = d.model.connect()
    assert d.one(Cmd.PREPOSITION, width=0.0, speed=50.0, conn=client).pending
    d.model.connection_lost(d.now + 0.1, client)
    assert flags_on(d, observer) & F.SF_FAST_STOP
    assert d.one(Cmd.PREPOSITION, width=10.0, speed=50.0, conn=observer).status == S.E_ACCESS_DENIED


def test_drop_without_fast_stop_when_switched_off_or_not_tcp(make_driver) -> None:
    d = make_driver(fast_stop_on_disconnect=False)
    c = d.model.connect()
    d.model.connection_lost(0.0, c)
    assert not flags(d) & F.SF_FAST_STOP
    d = make_driver()
    serial = d.model.connect(connection_oriented=False)
    assert d.one(Cmd.DISCONNECT, conn=serial).status == S.E_NOT_AVAILABLE  # §3.1.2: TCP only
    d.model.connection_lost(0.0, serial)
    assert not flags(d) & F.SF_FAST_STOP


def test_final_reply_goes_to_the_issuing_connection(homed) -> None:
    d = homed
    a, b = d.model.connect(), d.model.connect()
    assert d.one(Cmd.PREPOSITION, width=50.0, speed=100.0, conn=a).pending
    routed = []
    for _ in range(200):
        d.now += 0.01
        routed += d.model.advance_by_connection(d.now)
    assert [conn for conn, _ in routed] == [a]
    assert d.one(Cmd.GET_WIDTH, conn=b).fields["width"] == pytest.approx(50.0)


def test_model_parameters_are_validated() -> None:
    with pytest.raises(ValueError):
        WsgModel(stroke_mm=0)
    with pytest.raises(ValueError):
        WsgModel(firmware="four")


def decode_all(chunks: list[bytes]):
    parser = PacketParser()
    packets = [p for chunk in chunks for p in parser.feed(chunk)]
    assert all(isinstance(p, Packet) for p in packets)
    return [decode_reply(p.command, p.payload) for p in packets]


_IDS = sorted(
    {
        0x06,
        0x07,
        *range(0x20, 0x27),
        *range(0x30, 0x39),
        *range(0x40, 0x47),
        *range(0x50, 0x54),
        *range(0x60, 0x64),
        *range(0x70, 0x74),
        0x90,
    }
)


_WIDTH = st.floats(-20, 130, allow_nan=False)
_PAYLOADS = st.one_of(
    st.binary(max_size=12),
    st.just(b""),
    st.just(b"ack"),
    st.integers(0, 3).map(lambda d: bytes([d])),
    st.tuples(st.integers(0, 3), _WIDTH, st.floats(0, 500)).map(lambda t: struct.pack("<Bff", *t)),
    st.tuples(_WIDTH, st.floats(0, 500)).map(lambda t: struct.pack("<ff", *t)),
    st.tuples(st.integers(0, 3), st.integers(0, 100)).map(lambda t: struct.pack("<BH", *t)),
)


@given(
    steps=st.lists(
        st.tuples(st.sampled_from(_IDS), _PAYLOADS, st.floats(0, 0.5), st.integers(0, 2)),
        max_size=40,
    ),
    firmware=st.sampled_from(["4.0.1", "2.2.0"]),
    part=st.none() | st.floats(0, 110),
)
def test_any_request_sequence_gets_decodable_replies(steps, firmware, part) -> None:
    """Random ids and payloads on three connections: never a crash, every packet decodes, and every
    E_CMD_PENDING is followed by exactly one final reply with the same id on the same connection."""
    model = WsgModel(firmware=firmware, part_width_mm=part)
    conns = [0, model.connect(), model.connect(connection_oriented=False)]
    now = 0.0
    pending: dict[tuple[int, int], int] = {}

    def absorb(conn: int, chunks: list[bytes]) -> None:
        for reply in decode_all(chunks):
            key = (conn, reply.command)
            if reply.pending:
                assert pending.get(key, 0) == 0
                pending[key] = 1
            elif pending.get(key):
                pending[key] = 0

    for command, payload, dt, which in steps:
        now += dt
        for conn, data in model.advance_by_connection(now):
            absorb(conn, [data])
        conn = conns[which]
        if conn in (0, conns[1]) and model._connections[conn].announced:
            continue
        absorb(conn, model.handle(Packet(command, payload), now, conn))
    for _ in range(200):
        now += 0.5
        for conn, data in model.advance_by_connection(now):
            absorb(conn, [data])
    assert not any(pending.values()), pending


@pytest.mark.parametrize(
    ("kwargs", "match"), [({"serial": -1}, "serial"), ({"part_width_mm": -5}, "part_width")]
)
def test_impossible_parameters_are_refused_at_construction(kwargs: dict, match: str) -> None:
    with pytest.raises(ValueError, match=match):
        WsgModel(**kwargs)
