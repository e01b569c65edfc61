"""Issue 39 §2: one program on every family alike.

A motion's ``timeout=`` ending names the gripper (``PROFILE@URL``) and the command the user called on every
family: the WSG said ``wsg+tcp://…: PREPOSITION (21h): no final reply`` (its URL without the profile, its wire
command), the MSG named a grasp's opening move ``move``. The timeout (1 ms) is far shorter than the travel
asked for (most of the stroke at the default speed), so the motion cannot end first."""

from __future__ import annotations

import argparse
import subprocess
import sys
import warnings

import pytest

import grippers
from grippers import CommandFailed, GripperTimeout, GripperWarning
from grippers.errors import FastStopForgotten

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


def test_a_width_outside_the_soft_limits_names_them_not_the_status_code() -> None:
    """The WSG refuses a width outside the soft limits stored in it with E_RANGE_ERROR: the error names the
    limits and how to clear them (it said ``PREPOSITION (21h): E_RANGE_ERROR: Range error``)."""
    with grippers.open("sim://wsg50") as g:
        g.home()
        g.set_soft_limits(0.010, 0.040)
        for call in (lambda: g.move(0.045), lambda: g.grasp(0.045)):
            with pytest.raises(CommandFailed) as caught:
                call()
            text = str(caught.value)
            assert "outside the soft limits 10..40 mm" in text and "clear_soft_limits()" in text, text
            assert caught.value.status_name == "E_RANGE_ERROR"  # the device's word is kept for code
        g.clear_soft_limits()
        g.move(0.045)  # no soft limits: the same width is fine


def test_setting_the_wsg_force_limit_says_the_next_grasp_changes_it() -> None:
    """Issue 39 §2: ``settings --force-limit`` then a stronger grasp changed the limit silently. Setting it
    says so (a GripperWarning: a ``warning:`` line of the command), and a grasp does change it."""
    from grippers.backends import find_backend
    from grippers.backends.command_hooks import commands_of

    with grippers.open("sim://wsg50") as g:
        g.home()
        args = argparse.Namespace(
            soft_limits=None, clear_soft_limits=False, tag=None, acceleration=None, force_limit=20.0
        )
        with pytest.warns(GripperWarning, match="until the next grasp"):
            commands_of(find_backend("wsg")).change_settings(g, args, [])
        assert g.driver.force_limit() == pytest.approx(20.0)
        g.grasp(0.020, force=40.0)
        assert g.driver.force_limit() == pytest.approx(40.0)  # what the warning and docs/cli.md say


def test_closing_a_robotiq_that_is_fast_stopped_says_the_stop_is_forgotten() -> None:
    """Issue 39 §2: ``grippers stop R --fast`` then ``grippers move R 45`` moved a Robotiq: its fast-stop
    latch lived in one process, and nothing said so. The device keeps no latch of its own (no fast-stop state
    in its registers), so closing a latched one warns that the next program can move it."""
    g = grippers.open("sim://robotiq-2f85")
    g.home()
    g.fast_stop()
    with pytest.warns(FastStopForgotten, match="next command or program that opens it can move it"):
        g.close()
    with grippers.open("sim://robotiq-2f85") as g:  # acknowledged: nothing is forgotten
        g.home()
        g.fast_stop()
        g.acknowledge()
        with warnings.catch_warnings():
            warnings.simplefilter("error", FastStopForgotten)
            g.close()


def test_closing_a_wsg_that_is_fast_stopped_says_nothing() -> None:
    """The WSG latches its fast stop itself (SF_FAST_STOP): the next command sees it, nothing is forgotten."""
    with grippers.open("sim://wsg50") as g:
        g.fast_stop()
        with warnings.catch_warnings():
            warnings.simplefilter("error", FastStopForgotten)
            g.close()


def test_the_command_line_fast_stop_of_a_robotiq_says_it_is_forgotten() -> None:
    r = subprocess.run(
        [sys.executable, "-m", "grippers", "stop", "sim://robotiq-2f85", "--fast"],
        capture_output=True,
        text=True,
        timeout=60,
    )
    assert r.returncode == 0, r.stderr
    warning = [line for line in r.stderr.splitlines() if "warning:" in line]
    assert warning and "the fast stop ends with this session" in warning[0], r.stderr
