"""One scenario, every shipped profile, through ``grippers.open`` only: in-process and over a real transport.

The in-process case opens ``sim://PROFILE`` (a simulator served on loopback TCP or a virtual CAN bus inside
this process); the other starts ``grippers sim`` in a subprocess and connects to the URL it prints (TCP for
the WSG, the UART pseudo-terminal for the MSG), the way a user would reach hardware.
"""

from __future__ import annotations

import time

import pytest

import grippers
from grippers import GraspState, LimitError

from .conftest import SHIPPED, TIME_SCALE

PART_SHARE = 0.3  # the part's width as a share of the stroke: the moves stay above it


def _part_mm(profile: str) -> float:
    return round(grippers.load_profile(profile).mechanics.stroke_mm * PART_SHARE, 1)


def _open(kind: str, profile: str, sim_process) -> grippers.Gripper:
    part = _part_mm(profile)
    if kind == "in-process":
        return grippers.open(f"sim://{profile}?time_scale={TIME_SCALE}&part_width_mm={part}")
    family = "wsg" if profile.startswith("wsg") else "msg"
    listen = "tcp://127.0.0.1:0" if family == "wsg" else "pty"
    sim = sim_process(
        family,
        "--listen",
        listen,
        "--profile",
        profile,
        "--time-scale",
        str(TIME_SCALE),
        "--part-width",
        str(part),
    )
    return grippers.open(sim.url, profile=profile)


@pytest.mark.parametrize("kind", ["in-process", "subprocess"])
@pytest.mark.parametrize("profile", SHIPPED)
def test_scenario(profile: str, kind: str, sim_process) -> None:
    part = _part_mm(profile) / 1000
    with _open(kind, profile, sim_process) as g:
        assert g.profile.name == profile
        info = g.info()
        assert info.model == g.profile.model
        assert info.limits.max_width > part

        g.home()
        assert g.state().referenced

        top = g.limits.max_width
        result = g.move(top * 0.95)
        assert result.width == pytest.approx(top * 0.95, abs=0.002)

        # State is readable while a motion runs.
        handle = g.move(top * 0.5, g.limits.max_speed / 4, wait=False)
        seen_moving = False
        widths = []
        while not handle.done():
            st = g.state()
            widths.append(st.width)
            seen_moving |= st.moving
            time.sleep(0.002)
        handle.wait(5)
        assert seen_moving or len(set(widths)) > 1
        assert g.state().width == pytest.approx(top * 0.5, abs=0.002)

        g.release()
        grasp = g.grasp(part, force=g.limits.max_force / 2)
        assert grasp.grasped, grasp.reason
        assert grasp.state is GraspState.HOLDING
        assert grasp.width == pytest.approx(part, abs=0.003)
        assert g.state().grasp is GraspState.HOLDING

        g.release()
        assert g.state().grasp is GraspState.IDLE

        with pytest.raises(LimitError, match="outside"):
            g.move(top + 0.01)
        with pytest.raises(LimitError):
            g.grasp(part, force=g.limits.max_force * 2)

        # A motion that cannot finish in time raises a timeout, and the next command still works.
        with pytest.raises(grippers.GripperTimeout):
            g.move(top * 0.4, g.limits.min_speed, timeout=0.02)
        g.stop()
        assert g.state().width <= top

        g.fast_stop()
        with pytest.raises(grippers.GripperError, match="fast stop"):
            g.move(top * 0.6)
        g.acknowledge()
        assert "fast_stop" not in g.state().faults
        g.move(top * 0.6)
        assert g.state().width == pytest.approx(top * 0.6, abs=0.002)


@pytest.mark.parametrize("profile", ["wsg50", "msg-150"])
def test_capabilities_decide_what_is_supported(profile: str) -> None:
    with grippers.open(f"sim://{profile}?time_scale={TIME_SCALE}") as g:
        assert -20 < g.temperature() < 80  # both families' simulators report a plausible temperature
        if grippers.Capability.DEVICE_TAG in g.capabilities:
            g.set_device_tag("bench-1")
            assert g.device_tag() == "bench-1"
        else:
            with pytest.raises(grippers.NotSupported, match="device_tag"):
                g.device_tag()
        assert g.driver is not None  # vendor extras stay reachable


def test_wsg_2x_firmware_has_no_temperature() -> None:
    with grippers.open(f"sim://wsg50?time_scale={TIME_SCALE}&firmware=2.2.0") as g:
        assert g.info().firmware == "2.2.0"
        with pytest.raises(grippers.NotSupported, match="temperature"):
            g.temperature()


def test_msg_over_uart_has_no_temperature() -> None:
    with (
        grippers.open(f"sim://msg-150?time_scale={TIME_SCALE}&transport=pty") as g,
        pytest.raises(grippers.NotSupported),
    ):
        g.temperature()


def test_fast_stop_state_follows_the_device() -> None:
    """A fast stop acknowledged outside the API (here through the vendor client in ``.driver``) no longer
    blocks motion once the state has been read; one raised elsewhere blocks it."""
    with grippers.open(f"sim://wsg50?time_scale={TIME_SCALE}") as g:
        g.home()
        g.fast_stop()
        g.driver.acknowledge_fast_stop()
        assert not g.state().fast_stopped
        g.move(0.05)
        g.driver.fast_stop()
        assert g.state().fast_stopped
        with pytest.raises(grippers.FastStopActive):
            g.move(0.06)
