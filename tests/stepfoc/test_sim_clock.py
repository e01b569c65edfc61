"""The simulators' clock can be held still (issue 33 §5): a test that needs the device in the middle of
something pauses it, steps it, and resumes it, instead of racing a scaled clock against the scheduler."""

from __future__ import annotations

import time

import pytest

from grippers.drivers.simkit import SimClock


def test_a_paused_clock_stands_still_steps_and_resumes_where_it_was() -> None:
    clock = SimClock(1000.0, start=5.0)
    clock.pause()
    held = clock.now()
    time.sleep(0.02)  # 20 simulated s would pass on a running clock
    assert clock.now() == held
    clock.step(0.25)
    assert clock.now() == held + 0.25
    clock.resume()
    after = clock.now()
    assert held + 0.25 <= after < held + 0.25 + 1000.0 * 1.0  # runs on from the held time, no jump
    time.sleep(0.002)
    assert clock.now() > after


def test_step_needs_a_paused_clock_and_pause_twice_is_one_pause() -> None:
    clock = SimClock(10.0)
    with pytest.raises(RuntimeError, match="paused"):
        clock.step(1.0)
    clock.pause()
    first = clock.now()
    clock.pause()
    assert clock.now() == first
    clock.resume()
    clock.resume()  # resuming a running clock changes nothing
    assert clock.now() >= first
