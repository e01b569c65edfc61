"""The servo benchmark's arithmetic (benchmarks/servo.py): its lag fit finds a known shift. No timing."""

from __future__ import annotations

import sys
from pathlib import Path

REPO = Path(__file__).resolve().parents[2]
if str(REPO) not in sys.path:
    sys.path.insert(0, str(REPO))

from benchmarks import servo  # noqa: E402


def test_fit_finds_a_known_lag_and_zero_error_at_it() -> None:
    step = 0.001
    ideal = [(i * step, servo.target_mm(i * step)) for i in range(6000)]
    late = [(t, servo.target_mm(t - 0.037)) for t in (i * 0.005 for i in range(1000))]
    lag, rms_at_lag, rms0 = servo._fit(late, ideal)
    assert abs(lag - 0.037) < 0.001
    assert rms_at_lag < 0.05 < rms0


def test_ideal_paths_follow_the_sine() -> None:
    import grippers

    with grippers.open("sim://msg-150") as g:
        msg = servo._ideal_msg(g, 3.0, 0.001)
        wsg_profile = grippers.load_profile("wsg50")
    wsg = servo._ideal_wsg(wsg_profile, 3.0, 0.001)
    sine = [(i * 0.001, servo.target_mm(i * 0.001)) for i in range(4000)]
    for path in (msg, wsg):
        lag, _, _ = servo._fit(path, sine)
        assert lag < 0.1
