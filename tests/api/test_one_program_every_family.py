"""Issue 39 §2: one program on every family alike.

A motion's ``timeout=`` ending names the gripper (``PROFILE@URL``) and the command the user called on every
family: the WSG said ``wsg+tcp://…: PREPOSITION (21h): no final reply`` (its URL without the profile, its wire
command), the MSG named a grasp's opening move ``move``. The timeout (1 ms) is far shorter than the travel
asked for (most of the stroke at the default speed), so the motion cannot end first."""

from __future__ import annotations

import pytest

import grippers
from grippers import GripperTimeout

FAMILIES = ["sim://wsg50", "sim://msg-150", "sim://robotiq-2f85"]


@pytest.mark.parametrize("url", FAMILIES)
@pytest.mark.parametrize("command", ["move", "grasp", "release"])
def test_a_motion_timeout_names_the_gripper_and_the_users_command(url: str, command: str) -> None:
    with grippers.open(url) as g:
        g.home()
        lo, hi = g.limits.min_width, g.limits.max_width
        far = lo + 0.002 if g.state().width > (lo + hi) / 2 else hi - 0.002  # a travel of many timeouts
        calls = {
            "move": lambda: g.move(far, timeout=0.001),
            "grasp": lambda: g.grasp(lo + 0.001, timeout=0.001),  # the MSG first opens: still the grasp
            "release": lambda: g.release(far, timeout=0.001),
        }
        with pytest.raises(GripperTimeout) as caught:
            calls[command]()
        error = caught.value
        assert error.device == g.name, str(error)
        assert error.command == command, str(error)
        assert str(error).startswith(f"{g.name}: {command}: "), str(error)
        g.stop()
