"""Issue 31 §1: a move stopped by an obstacle, and a motion before homing, end the same way on every family.

Before: ``move(0.0)`` into a 40 mm part raised ``CommandFailed E_AXIS_BLOCKED`` on the WSG and returned
success (``MotionResult(width=0.0404, state=HOLDING)``) on the MSG; a motion before homing was
``E_NOT_INITIALIZED: Device was not initialized`` on the WSG and "move aborted: the jaws stopped at 2.5 mm ...
(the driver was idled or the motion stalled)" on the MSG, a ``grasp`` calling itself a "move".

The part holds the jaws still, so nothing here races the simulator's clock.
"""

from __future__ import annotations

import asyncio
from collections.abc import Iterator

import pytest

import grippers
import grippers.aio
from grippers import CommandFailed, GripperError, MotionBlocked, NotReferenced

from .conftest import TIME_SCALE

FAMILIES = ["wsg50", "msg-150"]
PART = 0.040


def test_the_two_errors_are_command_failures_exported_from_grippers() -> None:
    assert issubclass(MotionBlocked, CommandFailed) and issubclass(NotReferenced, CommandFailed)
    assert issubclass(NotReferenced, GripperError)
    assert {"MotionBlocked", "NotReferenced"} <= set(grippers.__all__)


@pytest.fixture(params=FAMILIES)
def homed(request: pytest.FixtureRequest) -> Iterator[grippers.Gripper]:
    with grippers.open(f"sim://{request.param}?part_width_mm={PART * 1000:g}&time_scale={TIME_SCALE}") as g:
        g.home()
        g.release()  # fully open, away from the part
        yield g


def test_a_move_into_a_part_raises_motion_blocked_with_the_width(homed: grippers.Gripper) -> None:
    with pytest.raises(MotionBlocked) as caught:
        homed.move(0.0)
    error = caught.value
    assert error.command == "move"
    assert error.width == pytest.approx(PART, abs=0.003)  # metres, where the jaws stopped
    assert error.target == 0.0
    assert "move blocked by an obstacle at 4" in str(error)
    assert homed.state().width == pytest.approx(error.width, abs=0.003)


def test_a_move_that_is_not_blocked_still_succeeds(homed: grippers.Gripper) -> None:
    result = homed.move(0.060)
    assert result.width == pytest.approx(0.060, abs=0.002)


def test_a_grasp_of_the_part_is_not_blocked(homed: grippers.Gripper) -> None:
    result = homed.grasp(PART)
    assert result.grasped


def test_a_handle_of_a_blocked_move_raises_it_too(homed: grippers.Gripper) -> None:
    handle = homed.move(0.0, wait=False)
    with pytest.raises(MotionBlocked):
        handle.wait()


@pytest.mark.parametrize("profile", FAMILIES)
def test_the_asyncio_face_raises_motion_blocked(profile: str) -> None:
    async def main() -> None:
        url = f"sim://{profile}?part_width_mm={PART * 1000:g}&time_scale={TIME_SCALE}"
        async with grippers.aio.open(url) as g:
            await g.home()
            await g.release()
            with pytest.raises(MotionBlocked) as caught:
                await g.move(0.0)
            assert caught.value.width == pytest.approx(PART, abs=0.003)

    asyncio.run(main())


@pytest.fixture(params=FAMILIES)
def unreferenced(request: pytest.FixtureRequest) -> Iterator[grippers.Gripper]:
    with grippers.open(f"sim://{request.param}?time_scale={TIME_SCALE}") as g:
        yield g


@pytest.mark.parametrize(
    ("command", "width"),
    [("move", 0.050), ("move", 0.001), ("grasp", 0.040), ("grasp", 0.100), ("release", 0.050)],
)
def test_a_motion_before_homing_is_not_referenced_naming_the_command(
    unreferenced: grippers.Gripper, command: str, width: float
) -> None:
    before = unreferenced.state().width
    with pytest.raises(NotReferenced) as caught:
        getattr(unreferenced, command)(width)
    error = caught.value
    assert error.command == command
    assert f"{command} refused: the gripper is not referenced; call home() first" in str(error)
    assert "stalled" not in str(error) and "aborted" not in str(error)
    assert unreferenced.state().width == pytest.approx(before, abs=1e-4)  # nothing moved
    unreferenced.home()  # and home() is the way out
    getattr(unreferenced, command)(width)


def test_the_wsg_keeps_the_device_status() -> None:
    with grippers.open(f"sim://wsg50?part_width_mm={PART * 1000:g}&time_scale={TIME_SCALE}") as g:
        with pytest.raises(NotReferenced) as caught:
            g.move(0.05)
        assert caught.value.status_name == "E_NOT_INITIALIZED"
        g.home()
        g.release()
        with pytest.raises(MotionBlocked) as blocked:
            g.move(0.0)
        assert blocked.value.status_name == "E_AXIS_BLOCKED"


def test_the_typed_errors_cross_the_remote_wire_with_their_fields() -> None:
    """A served gripper (zenoh://) raises them as itself: the class crosses by name, width and code too."""
    from grippers.remote import protocol

    blocked = MotionBlocked(width=0.0404, target=0.0, status=29, status_name="E_AXIS_BLOCKED", command="move")
    back = protocol.decode_error(protocol.encode_error(blocked, "move"), "move", "client-side")
    assert isinstance(back, MotionBlocked)
    assert (back.width, back.target, back.status_name) == (0.0404, 0.0, "E_AXIS_BLOCKED")
    refused = NotReferenced(status=3, status_name="E_NOT_INITIALIZED", command="grasp")
    back = protocol.decode_error(protocol.encode_error(refused, "grasp"), "grasp", "client-side")
    assert isinstance(back, NotReferenced) and back.command == "grasp" and back.status == 3
    assert "call home() first" in str(back)


@pytest.mark.parametrize("short", [0.0005, 0.003])
def test_a_move_that_ends_on_the_part_at_its_target_reached_it(homed: grippers.Gripper, short: float) -> None:
    """The one margin (MotionBlocked.MARGIN) on every family: touching the part where the jaws were sent
    is arriving; stopping 3 mm short is being blocked."""
    if short <= MotionBlocked.MARGIN:
        result = homed.move(PART - short)
        assert result.width == pytest.approx(PART, abs=0.002)
    else:
        with pytest.raises(MotionBlocked):
            homed.move(PART - short)


def test_the_msg_over_uart_follows_the_same_rule() -> None:
    url = f"sim://msg-150?transport=pty&part_width_mm={PART * 1000:g}&time_scale={TIME_SCALE}"
    with grippers.open(url) as g:
        with pytest.raises(NotReferenced, match="grasp refused"):
            g.grasp(0.030)
        g.home()
        g.release()
        with pytest.raises(MotionBlocked) as caught:
            g.move(0.0)
        assert caught.value.width == pytest.approx(PART, abs=0.003)
