"""The trapezoidal finger travel the model evaluates at arbitrary simulated times."""

from __future__ import annotations

import pytest
from hypothesis import given
from hypothesis import strategies as st

from grippers.drivers.wsg.sim.motion import Trapezoid


def test_long_move_cruises_at_speed() -> None:
    p = Trapezoid(t0=1.0, start=100.0, end=0.0, speed=50.0, accel=500.0)
    assert p.duration == pytest.approx(0.1 + 1.9 + 0.1)
    assert p.velocity(2.0) == -50.0
    assert p.position(1.05) == pytest.approx(100.0 - 0.5 * 500.0 * 0.05**2)
    assert p.position(p.t_end) == 0.0
    assert p.position(0.0) == 100.0


def test_short_move_is_a_triangle() -> None:
    p = Trapezoid(t0=0.0, start=0.0, end=1.0, speed=100.0, accel=100.0)
    assert p.duration == pytest.approx(0.2)  # 0.5 mm up in 0.1 s, 0.5 mm down
    assert p.velocity(0.1 - 1e-9) == pytest.approx(10.0)
    assert p.position(0.1) == pytest.approx(0.5)


def test_zero_distance() -> None:
    p = Trapezoid(t0=3.0, start=5.0, end=5.0, speed=10.0, accel=10.0)
    assert p.duration == 0.0 and p.position(4.0) == 5.0 and p.velocity(3.0) == 0.0


@given(
    start=st.floats(0, 200),
    end=st.floats(0, 200),
    speed=st.floats(1, 500),
    accel=st.floats(10, 10000),
    fractions=st.lists(st.floats(0, 1.2), min_size=2, max_size=20),
)
def test_profile_is_monotone_bounded_and_ends_on_target(start, end, speed, accel, fractions) -> None:
    p = Trapezoid(0.0, start, end, speed, accel)
    times = sorted(f * p.duration for f in fractions)
    xs = [p.position(t) for t in times]
    lo, hi = min(start, end), max(start, end)
    assert all(lo - 1e-9 <= x <= hi + 1e-9 for x in xs)
    steps = [(b - a) * p.direction for a, b in zip(xs, xs[1:], strict=False)]
    assert all(s >= -1e-9 for s in steps)
    assert all(abs(p.velocity(t)) <= speed + 1e-9 for t in times)
    assert p.position(p.t_end) == pytest.approx(end)
