"""Issue 33 §1: Ctrl-C during ``selftest``'s timed moves stops the jaws before exit 130.

The timed moves start with ``wait=False`` and poll ``state()``: the interrupt lands in the poll, outside any
blocking motion call, and ``close()`` lets a running motion run on (an MSG went from 31.7 to 51.5 mm after
"interrupted"). The simulated MSG is held still (its clock stopped) from the moment it moves until the
interrupt has been handled, so the test never races the simulator's clock; then its time runs again, and the
jaws must stay where they stopped.
"""

from __future__ import annotations

import signal
import threading
import time
from typing import Any

import pytest

from grippers.backends import get_backend
from grippers.cli import main, selftest
from grippers.drivers.simkit import SimClock
from grippers.drivers.stepfoc.sim.can_server import serve_can
from grippers.drivers.stepfoc.sim.model import Phase
from grippers.profiles import load_profile

SCALE = 20.0


class GearClock(SimClock):
    """Simulated time whose rate the test sets as it goes; rate 0 holds the device where it is."""

    def __init__(self, rate: float) -> None:
        super().__init__(rate)
        self._gear = threading.Lock()
        self._wall0 = time.monotonic()
        self._sim0 = 0.0

    def now(self) -> float:
        with self._gear:
            return self._sim0 + (time.monotonic() - self._wall0) * self.time_scale

    def set_rate(self, rate: float) -> None:
        with self._gear:
            wall = time.monotonic()
            self._sim0 += (wall - self._wall0) * self.time_scale
            self._wall0, self.time_scale = wall, rate

    def wall(self, simulated_seconds: float) -> float:
        return simulated_seconds / self.time_scale if self.time_scale else 0.01


def _wait_for(predicate: Any, what: str, timeout: float = 60.0) -> None:
    deadline = time.monotonic() + timeout
    while not predicate():
        assert time.monotonic() < deadline, f"no {what} within {timeout:g} s"
        time.sleep(0.005)


def test_ctrl_c_in_a_timed_move_stops_the_jaws(monkeypatch: pytest.MonkeyPatch) -> None:
    clock = GearClock(SCALE)
    model = get_backend("stepfoc").sim_model(load_profile("msg-150"), 0, None)
    server = serve_can(model, f"can://virtual/selftest-int-{time.monotonic_ns()}", clock=clock)
    timed = threading.Event()
    real_timed_move = selftest._timed_move

    def timed_move(*args: Any) -> Any:
        timed.set()
        return real_timed_move(*args)

    monkeypatch.setattr(selftest, "_timed_move", timed_move)

    def moving() -> bool:
        with server.lock:
            return model.phase is Phase.MOVING

    held: dict[str, float] = {}
    failure: list[BaseException] = []
    main_thread = threading.get_ident()

    def interrupt_once_moving() -> None:
        try:
            _wait_for(timed.is_set, "timed move")
            _wait_for(moving, "motion")
            clock.set_rate(0.0)  # the jaws hold still mid-move until the interrupt has been handled
            with server.lock:  # where the jaws are now: the server advances the model only when it runs
                model.advance(clock.now())
                held["mm"] = model.opening_mm
            signal.pthread_kill(main_thread, signal.SIGINT)
        except BaseException as exc:  # reported by the test body
            failure.append(exc)
            signal.pthread_kill(main_thread, signal.SIGINT)

    previous = signal.signal(signal.SIGINT, signal.default_int_handler)
    helper = threading.Thread(target=interrupt_once_moving, daemon=True)
    try:
        helper.start()
        code = main(["selftest", server.url, "--profile", "msg-150", "--yes", "--time-scale", str(SCALE)])
        helper.join(10)
        assert not failure, failure
        assert code == 130
        with server.lock:
            stopped_mm, phase = model.opening_mm, model.phase
        assert abs(stopped_mm - held["mm"]) < 0.5 and phase is not Phase.MOVING, (held, stopped_mm, phase)
        # Time runs again: a motion left running would carry the jaws on to the move's target (tens of mm).
        clock.set_rate(SCALE)
        resumed = clock.now()
        _wait_for(lambda: clock.now() > resumed + 5.0, "simulated time")
        with server.lock:
            later_mm = model.opening_mm
        assert abs(later_mm - stopped_mm) < 0.5, (stopped_mm, later_mm)
    finally:
        signal.signal(signal.SIGINT, previous)
        clock.set_rate(SCALE)
        server.close()


def test_stops_motions_on_error_stops_only_when_the_block_fails() -> None:
    # The helper every command that starts motions without waiting can use (grippers/cli/common.py).
    import grippers
    from grippers.cli.common import stops_motions_on_error
    from grippers.errors import CommandFailed

    clock = GearClock(SCALE)
    model = get_backend("stepfoc").sim_model(load_profile("msg-150"), 0, None)
    server = serve_can(model, f"can://virtual/stops-{time.monotonic_ns()}", clock=clock)
    gripper = grippers.open(server.url, profile="msg-150")
    try:
        gripper.home()
        clock.set_rate(0.0)  # from here the jaws cannot finish a move: "still running" is certain
        with stops_motions_on_error(gripper):
            left_alone = gripper.move(0.08, wait=False)
        assert not left_alone.done()  # a block that ends normally leaves its motion running
        with pytest.raises(RuntimeError, match="the command failed"), stops_motions_on_error(gripper):
            handle = gripper.move(0.03, wait=False)
            raise RuntimeError("the command failed")
        assert handle.done()
        with pytest.raises(CommandFailed, match="aborted by RuntimeError"):
            handle.wait(0)
        with server.lock:
            assert model.phase is not Phase.MOVING
    finally:
        clock.set_rate(SCALE)
        gripper.close()
        server.close()
