"""One scenario, every shipped profile, through ``grippers.open`` only: in-process and over a real transport.

The in-process case opens ``sim://PROFILE`` (a simulator served on loopback TCP or a virtual CAN bus inside
this process); the other starts ``grippers sim`` in a subprocess and connects to the URL it prints (TCP for
the WSG, the UART pseudo-terminal for the MSG), the way a user would reach hardware.
"""

from __future__ import annotations

from collections.abc import Callable
from contextlib import AbstractContextManager

import pytest

import grippers

from ..scenario import run_scenario
from ..simhold import MSG_CREEP_S, held
from .conftest import SHIPPED, TIME_SCALE

PART_SHARE = 0.3  # the part's width as a share of the stroke: the moves stay above it


def _part_mm(profile: str) -> float:
    return round(grippers.load_profile(profile).mechanics.stroke_mm * PART_SHARE, 1)


def _open(
    kind: str, profile: str, sim_process
) -> tuple[grippers.Gripper, Callable[[], AbstractContextManager[object]]]:
    """The gripper, and what holds its simulated device still (tests/simhold.py in-process; the subprocess's
    hold signal otherwise)."""
    part = _part_mm(profile)
    if kind == "in-process":
        g = grippers.open(f"sim://{profile}?time_scale={TIME_SCALE}&part_width_mm={part}")
        return g, lambda: held(g, creep=MSG_CREEP_S)
    # `grippers sim FAMILY` for every family (issue 28 §2): the profile's own family names the command.
    family = grippers.load_profile(profile).family
    listen = "tcp://127.0.0.1:0" if family == "wsg" else "pty"  # the WSG's default port needs root
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
    return grippers.open(sim.url, profile=profile), sim.held


@pytest.mark.parametrize("kind", ["in-process", "subprocess"])
@pytest.mark.parametrize("profile", SHIPPED)
def test_scenario(profile: str, kind: str, sim_process) -> None:
    g, hold = _open(kind, profile, sim_process)
    with g:
        run_scenario(g, profile, _part_mm(profile) / 1000, hold)


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
