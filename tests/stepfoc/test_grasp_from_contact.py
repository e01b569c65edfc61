"""A grasp that starts with the jaws already pressing on the part (a servo, a move or an earlier grasp left
them there) is a grasp, not "reached ... without meeting a part".

Found under load by tests/servo/test_newer_wins.py (servo then grasp): the simulator pushed with the sign of a
velocity the jaws never had (zero travel counted as opening), so it flagged an opening object while closing;
the firmware's current follows the position error, towards the commanded target.
"""

from __future__ import annotations

import time

import pytest

import grippers

URLS = {
    "can": "sim://msg-150?time_scale=10&part_width_mm=40",
    "uart": "sim://msg-150?time_scale=10&part_width_mm=40&transport=pty",
}


@pytest.mark.parametrize("transport", sorted(URLS))
@pytest.mark.filterwarnings("ignore::grippers.ProfileAssumed")
def test_grasp_from_jaws_already_on_the_part_is_held(transport: str) -> None:
    with grippers.open(URLS[transport]) as g:
        g.home()
        g.move((g.limits.min_width + g.limits.max_width) / 2)
        g.servo(g.limits.min_width + 0.002, max(g.limits.min_speed * 2, 0.005))
        deadline = time.monotonic() + 30.0
        while True:  # until the servoed jaws stand on the part
            st = g.state()
            if not st.moving and abs(st.width - 0.040) < 2e-3:
                break
            assert time.monotonic() < deadline, st
            time.sleep(0.02)
        result = g.grasp(0.040)
        assert result.grasped, result
        assert g.state().grasp is grippers.GraspState.HOLDING
