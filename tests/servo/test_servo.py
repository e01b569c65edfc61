"""Streamed targets against the simulators over their real transports (loopback TCP, virtual CAN, a pty)."""

from __future__ import annotations

import time
from collections.abc import Iterator

import pytest

import grippers
from grippers import ConnectionLost, GripperError, LimitError
from grippers.drivers.stepfoc.sim.model import Mode

WSG = ["sim://wsg50?time_scale=10", "sim://wsg50?time_scale=10&firmware=2.2.0"]
MSG = ["sim://msg-150?time_scale=10", "sim://msg-150?time_scale=10&transport=pty"]


def _settle(g: grippers.Gripper, width: float, timeout: float = 5.0) -> list[float]:
    """Widths seen until the gripper rests at ``width`` (within 1 mm)."""
    seen = []
    deadline = time.monotonic() + timeout
    while time.monotonic() < deadline:
        st = g.state()
        seen.append(st.width)
        if not st.moving and abs(st.width - width) < 1e-3:
            return seen
        time.sleep(0.005)
    raise AssertionError(f"did not settle at {width}: last {seen[-5:]}")


@pytest.fixture(params=WSG + MSG)
def gripper(request: pytest.FixtureRequest) -> Iterator[grippers.Gripper]:
    with grippers.open(request.param) as g:
        g.home()
        yield g


def test_latest_target_wins_and_coalesces(gripper: grippers.Gripper) -> None:
    gripper.move(0.05)
    for i in range(300):  # as fast as Python goes: far faster than any device takes commands
        gripper.servo(0.03 + 0.02 * (i % 7) / 7)
    gripper.servo(0.062)
    assert gripper.servo_flush(5.0)
    stats = gripper.servo_stats
    assert stats.received == 301
    assert stats.sent + stats.coalesced + stats.unchanged == stats.received
    assert stats.coalesced > 0 and stats.failed == 0
    _settle(gripper, 0.062)


def test_a_new_target_takes_effect_without_waiting_for_the_motion(gripper: grippers.Gripper) -> None:
    """A far target at a low speed, replaced at once by a near one: the fingers never go near the first."""
    gripper.move(0.05)
    slow = gripper.limits.min_speed * 2
    gripper.servo(0.005, speed=slow)
    assert gripper.servo_flush(2.0)
    time.sleep(0.02)
    gripper.servo(0.055)
    seen = _settle(gripper, 0.055, timeout=3.0)
    # Waiting for the first target would have taken the fingers to 5 mm (a loaded machine may let them travel
    # some way before the second target lands, hence the margin).
    assert min(seen) > 0.015


def test_limits_are_checked_on_every_call_and_nothing_is_sent(gripper: grippers.Gripper) -> None:
    gripper.servo(0.04)
    before = gripper.servo_stats.received
    with pytest.raises(LimitError):
        gripper.servo(gripper.limits.max_width + 0.01)
    with pytest.raises(LimitError):
        gripper.servo(0.04, speed=float("nan"))
    with pytest.raises(LimitError):
        gripper.servo(0.04, force=gripper.limits.max_force * 2)
    assert gripper.servo_stats.received == before


def test_stop_ends_servoing_and_a_move_takes_over(gripper: grippers.Gripper) -> None:
    gripper.move(0.06)
    gripper.servo(0.01, speed=gripper.limits.min_speed * 2)
    assert gripper.servo_flush(2.0)
    gripper.stop()
    assert not gripper.servoing
    time.sleep(0.05)
    a = gripper.state()
    time.sleep(0.1)
    assert abs(gripper.state().width - a.width) < 1e-3  # stopped, not still heading for 10 mm
    gripper.servo(0.02, speed=gripper.limits.min_speed * 2)
    assert gripper.servo_flush(2.0)
    # A motion command ends servoing and is not refused because the servo motion still runs (WSG:
    # E_ALREADY_RUNNING without the STOP the servo end sends).
    result = gripper.move(0.045)
    assert abs(result.width - 0.045) < 1e-3
    assert not gripper.servoing


def test_an_error_on_the_device_is_raised_by_the_next_call() -> None:
    with grippers.open(WSG[0]) as g:
        g.home()
        g.driver.fast_stop()  # behind the Gripper's back: the device refuses motion from now on
        g.servo(0.03)
        g.servo_flush(2.0)
        with pytest.raises(GripperError) as info:
            g.servo(0.04)
        assert "E_ACCESS_DENIED" in str(info.value)
        assert g.servo_stats.failed == 1


def test_msg_first_target_equal_to_the_last_61_still_moves() -> None:
    """docs/protocols.md §2: a 5-byte 61 equal to the previous one is "same command" and ignored."""
    with grippers.open(MSG[0]) as g:
        g.home()
        g.move(0.04)
        node, model = g.driver, g.simulator.model
        g.driver.idle()  # command 12: the motor idles with the 61 it last got still stored
        g.state()  # a round trip: the idle frame (no reply) has been handled before it
        assert model.mode is Mode.IDLE  # the firmware idles the driver; the stored 61 keeps its action bit
        same = node.last_command
        speed = round(g.profile.mechanics.default_speed_mm_s / 1000, 6)
        g.servo(0.04, speed=speed)
        assert g.servo_flush(2.0)
        assert node.last_command.position == same.position
        assert node.last_command != same  # made to differ, so the firmware takes it
        assert model.mode is Mode.GRIPPER and model.action  # taken: the gripper holds its target again


def test_closed_gripper_refuses_servo() -> None:
    g = grippers.open(WSG[0])
    g.servo(0.03)
    g.close()
    with pytest.raises(GripperError):
        g.servo(0.03)
    assert not isinstance(GripperError("x"), ConnectionLost)
