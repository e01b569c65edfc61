"""Issue 23 §1: a WSG stop goes out at once and nothing that queued before it goes out after it.

Reported: ``servo()`` during a running ``move()`` made a later ``stop()`` take 1.5 s, and the jaws travelled
15 mm more. At the client, the servo targets are motion requests waiting for the 21h slot the running move
holds; STOP ends the move, which frees the slot, and the queued target then started a new motion right after
the stop. A stop now fences them: a motion request still waiting for its turn when a stop is sent ends with
E_CMD_ABORTED instead of going out. The simulator runs at real time here, so distances are the device's.
"""

from __future__ import annotations

import threading
import time

import pytest

import grippers
from grippers.drivers.errors import CommandFailed, GripperError
from grippers.drivers.wsg.client import WsgClient
from grippers.drivers.wsg.commands import SystemFlags

SPEED = 20.0  # mm/s: the running move's speed, and the queued targets'


def _one_exchange(c: WsgClient) -> float:
    """The longest of a few LOOP round trips now: what one exchange costs on this machine at this moment."""
    longest = 0.0
    for _ in range(5):
        t0 = time.monotonic()
        c.loop(b"t")
        longest = max(longest, time.monotonic() - t0)
    return longest


def test_stop_is_not_followed_by_motions_queued_before_it(wsg_sim, wsg_connect) -> None:
    server = wsg_sim("tcp://127.0.0.1:0", time_scale=1.0)
    c = wsg_connect(server.url, timeout=1.0)
    c.home(timeout=10.0)
    c.preposition(90.0, 400.0, timeout=5.0)
    move = c.preposition(10.0, SPEED, wait=False)  # 4 s of travel
    assert move is not None

    halt = threading.Event()
    outcomes: list[BaseException | None] = []

    def stream() -> None:
        """A servo loop's traffic: a far target again and again, each queued behind the running move."""
        while not halt.is_set():
            try:
                c.preposition(100.0, SPEED, wait=False)
                outcomes.append(None)
            except GripperError as exc:
                outcomes.append(exc)

    streamer = threading.Thread(target=stream, daemon=True)
    streamer.start()
    time.sleep(0.3)  # the move runs, the stream's request waits for the 21h slot

    exchange = _one_exchange(c)
    before = c.width()
    halt.set()
    c.stop()
    streamer.join(5.0)
    assert not streamer.is_alive()

    # The fingers come to rest and stay there: no queued target went out after the stop.
    deadline = time.monotonic() + 2.0
    while c.system_state() & SystemFlags.SF_MOVING:
        assert time.monotonic() < deadline, "still moving after stop(): a queued motion went out after it"
        time.sleep(0.01)
    rest = c.width()
    time.sleep(0.3)
    assert c.width() == pytest.approx(rest, abs=0.05)
    # Travel after the width was read: the device's speed over a few exchanges (the width's reply, the STOP),
    # plus a millimetre for the deceleration and the position's resolution.
    assert abs(rest - before) <= SPEED * 4 * exchange + 1.0
    with pytest.raises(CommandFailed) as info:
        move.result(timeout=2.0)
    assert info.value.status_name == "E_CMD_ABORTED"
    last = outcomes[-1]
    assert isinstance(last, CommandFailed) and last.status_name == "E_CMD_ABORTED", outcomes[-3:]


def test_gripper_stop_during_a_move_and_a_servo_stream_goes_out_at_once() -> None:
    """The reported case through the Gripper API: stop() while a move() runs and servo() targets stream."""
    speed = SPEED / 1000
    with grippers.open("sim://wsg50") as g:  # real time
        g.home()
        g.move(0.09)
        errors: list[BaseException] = []

        def move() -> None:
            try:
                g.move(0.01, speed=speed)
            except GripperError as exc:
                errors.append(exc)

        mover = threading.Thread(target=move, daemon=True)
        mover.start()
        time.sleep(0.3)
        for i in range(20):
            g.servo(0.05 + 0.001 * i, speed=speed)
            time.sleep(0.01)
        exchange = _one_exchange(g.driver)
        before = g.state().width  # five exchanges
        g.stop()
        mover.join(5.0)
        deadline = time.monotonic() + 2.0
        while g.state().moving:
            assert time.monotonic() < deadline
            time.sleep(0.01)
        rest = g.state().width
        # Was 15 mm: stop() waited for the servo thread, itself waiting behind the move for the 21h slot.
        assert abs(rest - before) * 1000 <= SPEED * 8 * exchange + 1.0
        # The first servo() took over from the move (the newer command wins, tests/servo/test_newer_wins.py),
        # so the move reports that, never success.
        assert errors and "superseded by servo" in str(errors[0])
