"""An in-process simulator's exchange timeout is at least grippers.timeouts.SIM_MIN_TIMEOUT_S unless given.

Busy CI runs (docs/reliability.md, N11) failed three MSG checks on ``sim://msg-150``, each a 0.5 s reply
bound overrun by a simulator thread that shares the client's process and interpreter lock on a starved CPU:
lateness a device never has. A profile's longer timeout and the user's ``timeout=`` stand.
"""

from __future__ import annotations

import pytest

import grippers
from grippers.settings import Settings
from grippers.testing import GripperSims
from grippers.timeouts import SIM_MIN_TIMEOUT_S


@pytest.mark.parametrize("url", ["sim://msg-150", "sim://msg-150?transport=pty", "sim://wsg50"])
def test_an_in_process_simulator_waits_at_least_the_floor(url: str) -> None:
    with grippers.open(url) as g:
        assert g.timeout == SIM_MIN_TIMEOUT_S


@pytest.mark.parametrize("transport", ["can", "pty"])
def test_a_url_served_in_this_process_is_floored_as_sim_is(gripper_sim: GripperSims, transport: str) -> None:
    """The gripper_sim fixture's and the conformance suite's URLs (grippers.testing.SimURL) carry their
    in-process simulator: opened, they get the floor; the same text as a plain string is hardware's."""
    url = gripper_sim("msg-150", transport=transport)
    with grippers.open(url) as g:
        assert g.timeout == SIM_MIN_TIMEOUT_S
    with grippers.open(str(url)) as g:
        assert g.timeout == 0.5  # the msg-150 profile's
    with grippers.open(url, timeout=0.3) as g:
        assert g.timeout == 0.3


@pytest.mark.parametrize("given", [0.3, 7.0])
def test_a_given_timeout_stands(given: float) -> None:
    with grippers.open("sim://msg-150", timeout=given) as g:
        assert g.timeout == given
    with grippers.open(f"sim://msg-150?timeout={given}") as g:
        assert g.timeout == given


def test_a_longer_default_stands_and_the_floor_is_only_for_what_was_not_given() -> None:
    settings = Settings("sim://x", {"speed": "3"}, {})
    settings.at_least("timeout", 2.0)
    settings.at_least("speed", 10.0)
    assert settings.positive("timeout", 5.0) == 5.0  # a profile's longer timeout
    assert settings.positive("speed", 1.0) == 3.0  # given: not floored
    other = Settings("sim://x", {}, {})
    other.at_least("timeout", 2.0)
    assert other.positive("timeout", 0.5) == 2.0


def test_hardware_urls_keep_the_profile_default() -> None:
    settings = Settings("stepfoc+serial:///dev/ttyUSB0", {}, {})
    assert settings.positive("timeout", 0.5) == 0.5
