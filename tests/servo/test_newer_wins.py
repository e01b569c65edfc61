"""A newer command wins in every pair of move, grasp, home and servo, on both families (issue 23 §1).

The first command runs when the second is given; the first never reports success (a motion raises
"superseded by …"), the second does what it was asked, and a superseded call's backend work has ended by the
time the second command has taken over (an MSG home() overtaken by servo() used to run on to its timeout).
Simulators over real transports: WSG over loopback TCP, MSG over a python-can virtual bus and a pty.
"""

from __future__ import annotations

import itertools
import time
from collections.abc import Callable, Iterator
from typing import Any

import pytest

import grippers
from grippers import CommandFailed
from tests.simhold import MSG_CREEP_S, held, step_until

COMMANDS = ("move", "grasp", "home", "servo")
URLS = {
    "wsg": "sim://wsg50?time_scale=10&part_width_mm=40",
    "msg": "sim://msg-150?time_scale=10&part_width_mm=40",
    "msg-uart": "sim://msg-150?time_scale=10&part_width_mm=40&transport=pty",
}


def _until(what: str, predicate: Callable[[], bool], timeout: float = 20.0) -> None:
    deadline = time.monotonic() + timeout
    while not predicate():
        if time.monotonic() > deadline:
            raise AssertionError(f"{what}: not within {timeout:g} s")
        time.sleep(0.01)


@pytest.fixture(scope="module", params=sorted(URLS))
def gripper(request: pytest.FixtureRequest) -> Iterator[grippers.Gripper]:
    with grippers.open(URLS[request.param]) as g:
        g.home()
        yield g


def _start(g: grippers.Gripper, command: str, width: float, speed: float) -> Any:
    """Start ``command`` without waiting; a handle for motions, None for servo."""
    if command == "move":
        return g.move(width, speed, wait=False)
    if command == "grasp":
        return g.grasp(0.04, speed, wait=False)
    if command == "home":
        return g.home(wait=False)
    g.servo(width, speed)
    return None


def _at(g: grippers.Gripper, width: float) -> bool:
    st = g.state()
    return abs(st.width - width) < 1.5e-3 and not st.moving


def _supersede(g: grippers.Gripper, first: str, second: str, target: float) -> Any:
    """Give the second command without waiting for it (its registration supersedes the first at once);
    a handle to wait on afterwards, or None (servo)."""
    if second == "servo":
        g.servo(target)
        return None
    if second == "move":
        return g.move(target, wait=False)
    if second == "grasp":
        if first == "grasp":
            # the part lies in the first grasp's way: the move that supersedes it is the newer command
            return g.move(target, wait=False)
        return g.grasp(0.04, wait=False)
    return g.home(wait=False)


@pytest.mark.parametrize(("first", "second"), list(itertools.product(COMMANDS, COMMANDS)))
def test_the_newer_command_wins(gripper: grippers.Gripper, first: str, second: str) -> None:
    """The simulator's clock is held still from the first command's start until the second has been
    given (issue 33 §5): with a running clock, a busy machine could let the first command end before the
    second arrived ("DID NOT RAISE" for wsg-home-move)."""
    g = gripper
    lo, hi = g.limits.min_width, g.limits.max_width
    middle = (lo + hi) / 2
    slow = max(g.limits.min_speed * 2, 0.005)
    g.move(middle)  # from the middle, every first command has a long way to go
    g.stop()  # ends a servoing left by the previous case
    target = hi - 0.005
    with held(g, creep=MSG_CREEP_S if g.profile.name.startswith("msg") else 0.0) as clock:
        handle = _start(g, first, lo + 0.002 if first != "grasp" else 0.0, slow)
        step_until(clock, lambda: abs(g.state().width - middle) > 1e-3, f"{first} under way")
        newer = _supersede(g, first, second, target)

    if second == "move":
        result = newer.wait()
        assert abs(result.width - target) < 1.5e-3
    elif second == "grasp":
        if first == "grasp":
            newer.wait()  # the first grasp ended; the part lies between the jaws again for the second
            newer = g.grasp(0.04, wait=False)
        result = newer.wait()
        assert result.grasped, result
    elif second == "home":
        newer.wait()

    if handle is not None:
        with pytest.raises(CommandFailed, match="superseded"):
            handle.wait(0)  # settled the moment the newer command took over, never a success
        # Its backend call has returned: nothing of it lands after the newer command (a superseded MSG home
        # polled on to its 30 s timeout).
        assert not handle._busy()
    else:
        assert not g.servoing or second == "servo"  # a motion command ended servoing
    if second == "servo":
        _until("servo target reached", lambda: _at(g, target))
    g.stop()
