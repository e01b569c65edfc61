"""grippers.units: the one place the generic code converts (issue 32 §4, issue 40 §6)."""

from __future__ import annotations

import pytest

from grippers import units


def test_millimetres_and_metres_round_trip() -> None:
    assert units.to_mm(0.0315) == pytest.approx(31.5)
    assert units.to_m(31.5) == pytest.approx(0.0315)
    assert units.to_mm(None) is None and units.to_m(None) is None


def test_milliamperes_milliseconds_and_nanoseconds() -> None:
    assert units.to_amps(1500) == 1.5 and units.to_amps(None) is None
    assert units.to_ms(0.25) == 250.0
    assert units.to_ns(1.5) == 1_500_000_000
    assert units.split_ns(3_000_000_007) == (3, 7)


@pytest.mark.parametrize(("t", "ms"), [(1700000000.25, 250), (12.999, 999), (5.0, 0), (0.0004, 0)])
def test_the_millisecond_of_a_clock_reading(t: float, ms: int) -> None:
    assert units.millisecond_of(t) == ms
