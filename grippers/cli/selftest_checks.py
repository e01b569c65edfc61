"""The arithmetic of ``grippers selftest``: speeds from sampled widths, verdicts, and the measured profile.

Pure functions over numbers (no device, no I/O), so the rules are tested on their own and the command stays
a sequence of steps. Every tolerance is the user's relative ``tolerance`` plus the uncertainty of the
measurement itself, computed from the samples of that run (the standard error of a fitted slope, or the
poll interval against the motion's duration): a coarse measurement widens its own bound instead of the bound
being tuned to one machine's speed, and a measurement too coarse to mean anything is a WARN, never a PASS.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass
from typing import Any, Literal

Verdict = Literal["PASS", "WARN", "INFO"]

MIDDLE = 0.15  # the first and last 15 % of the travel are left out of the speed fit (acceleration, settling)
MIN_FIT_SAMPLES = 4
PLATEAU = 0.9  # samples whose reported speed is within 10 % of the move's peak are its cruise
STANDARD_ERRORS = 3.0  # a measured value within 3 standard errors of its bound is not a deviation
MAX_UNCERTAINTY = 0.5  # beyond ±50 % a measured speed says nothing: WARN "too coarse"


@dataclass(frozen=True)
class Line:
    """One row of the table: what was measured against what the profile (or the library) expects."""

    check: str
    measured: str
    expected: str
    verdict: Verdict
    note: str = ""
    value: float | None = None  # the measured number, in the unit of ``check``, for --json and the profile


@dataclass(frozen=True)
class SpeedMeasurement:
    requested: float  # mm/s
    measured: float  # mm/s, device time
    uncertainty: float  # relative (0.05 = ±5 %)
    samples: int
    method: str  # "fit" or "duration"


def fit_speed(
    samples: Sequence[tuple[float, float]],
    start_mm: float,
    end_mm: float,
    duration_s: float,
    poll_s: float,
    reported: Sequence[float | None] = (),
) -> tuple[float, float, int, str]:
    """(speed mm/s, relative uncertainty, samples used, method) of one move from ``(t_s, width_mm)`` samples.

    The speed is the slope of a least-squares line through the samples in the middle of the travel, where the
    jaws cruise; its uncertainty is ``STANDARD_ERRORS`` standard errors of that slope (timing jitter and the
    width's resolution both show in the residuals). With too few samples in the middle (a fast move, a slow
    link) the travel over the whole call's duration is shown instead, with an unbounded uncertainty: a WARN
    "too coarse", since that figure hides the ramps and the link's latency.

    Where the device reports its own speed with each state (``reported``, the WSG), the fit takes the samples
    of the plateau instead (reported speed within ``PLATEAU`` of its peak), so a move that spends much of the
    span accelerating is still judged by its cruise, even where the acceleration is unknown (a served
    gripper). Only the choice of samples comes from the report; the speed is always the widths' slope.
    """
    distance = abs(end_mm - start_mm)
    lo, hi = sorted((start_mm, end_mm))
    margin = MIDDLE * distance
    middle = [(t, w) for t, w in samples if lo + margin <= w <= hi - margin]
    speeds = [abs(v) for v in reported if v is not None]
    if len(speeds) == len(samples) and speeds and max(speeds) > 0:
        peak = max(speeds)
        plateau = [sample for sample, v in zip(samples, speeds, strict=True) if v >= PLATEAU * peak]
        if len(plateau) >= MIN_FIT_SAMPLES:
            middle = plateau
    if len(middle) >= MIN_FIT_SAMPLES:
        n = len(middle)
        t_mean = sum(t for t, _ in middle) / n
        w_mean = sum(w for _, w in middle) / n
        stt = sum((t - t_mean) ** 2 for t, _ in middle)
        if stt > 0:
            slope = sum((t - t_mean) * (w - w_mean) for t, w in middle) / stt
            residual = sum((w - (w_mean + slope * (t - t_mean))) ** 2 for t, w in middle)
            se = math.sqrt(residual / (n - 2) / stt) if n > 2 else math.inf
            speed = abs(slope)
            if speed > 0:
                return speed, STANDARD_ERRORS * se / speed, n, "fit"
    # The travel over the call's duration is only a lower bound of the cruise speed (the ramps, the command's
    # round trip and the last poll are in the duration), by an amount nothing here measures: shown, never
    # judged.
    speed = distance / duration_s if duration_s > 0 else 0.0
    return speed, math.inf, len(samples), "duration"


def speed_verdict(m: SpeedMeasurement, tolerance: float) -> Line:
    ratio = m.measured / m.requested if m.requested > 0 else math.inf
    bound = tolerance + m.uncertainty
    spread = f"±{m.uncertainty * 100:.0f} %" if m.uncertainty <= MAX_UNCERTAINTY else "not fitted"
    shown = f"{m.measured:.1f} mm/s (x{ratio:.2f}, {spread})"
    if m.uncertainty > MAX_UNCERTAINTY:
        verdict: Verdict = "WARN"
        note = f"too coarse to judge ({m.samples} samples): run at real time or on a quieter link"
    elif abs(ratio - 1) <= bound:
        verdict, note = "PASS", ""
    else:
        verdict = "WARN"
        note = (
            f"the jaws moved {ratio:.2f}x the requested speed: the profile's speed map does not fit this unit"
        )
    return Line(
        f"speed {m.requested:g} mm/s",
        shown,
        f"{m.requested:g} mm/s ±{bound * 100:.0f} %" if math.isfinite(bound) else f"{m.requested:g} mm/s",
        verdict,
        note,
        m.measured,
    )


def test_speeds(
    min_speed: float, max_speed: float, span: float, fractions: Sequence[float], accel: float | None
) -> list[float]:
    """The speeds (mm/s) to move at: fractions of the top speed, where the top is also capped so that the
    jaws cruise over the middle of the span a fit uses: accelerating to v takes v²/2a, which must stay within
    the ``MIDDLE`` share of the span at each end (``accel`` in mm/s², None where the device does not say)."""
    top = max_speed
    if accel is not None and accel > 0:
        top = min(top, math.sqrt(2 * accel * MIDDLE * span) / max(fractions))
    return [min(max(min_speed, round(f * top, 1)), max_speed) for f in fractions]


def speed_factor(requested: Sequence[float], measured: Sequence[float]) -> float:
    """How much faster the jaws move than asked, one factor for every speed: measured = factor x requested.

    The firmware's speed map (drivers/stepfoc/speed.py: ticks per second per speed byte) is fixed; what a
    unit can get wrong is the profile's ``maps.ticks_per_mm``, which scales every speed alike. So one factor,
    fitted by least squares through the origin; a line with its own intercept, fitted on three noisy points,
    put the slow end anywhere (tried: 68 mm/s of a 0..300 mm/s map).
    """
    return sum(r * m for r, m in zip(requested, measured, strict=True)) / sum(r * r for r in requested)


def fitted_speed_map(
    requested: Sequence[float], measured: Sequence[float], at_0: float, at_255: float
) -> tuple[float, float]:
    """The speed map's two ends (mm/s at speed byte 0 and 255) that make a request the jaws' speed."""
    factor = speed_factor(requested, measured)
    return at_0 * factor, at_255 * factor


def measured_profile(
    profile: Any,
    lines: Sequence[Line],
    speeds: Sequence[SpeedMeasurement],
    name: str,
    stroke_mm: float | None,
) -> dict[str, Any]:
    """A profile document that ``extends`` ``profile`` with what was measured (only what differs).

    MSG: ``maps.ticks_per_mm`` refitted (the speed map follows from it), and the mechanics' speed range kept
    inside what the new map can do (a request above the map's fast end would be clamped to byte 255 and run
    slower than asked). WSG: the stroke the device reports, when it differs from the profile's.
    """
    doc: dict[str, Any] = {
        "extends": profile.name,
        "name": name,
        "description": f"{profile.model} as measured by grippers selftest",
        "source": "grippers selftest: "
        + "; ".join(f"{ln.check}: {ln.measured}" for ln in lines if ln.check.startswith(("speed", "stroke"))),
    }
    mech = profile.mechanics
    mechanics: dict[str, Any] = {}
    maps = getattr(profile, "maps", None)
    usable = [s for s in speeds if s.uncertainty <= MAX_UNCERTAINTY]
    if maps is not None and usable:
        low, high = fitted_speed_map(
            [s.requested for s in usable],
            [s.measured for s in usable],
            maps.speed_at_0_mm_s,
            maps.speed_at_255_mm_s,
        )
        # Jaws factor x faster than asked: each mm takes factor x fewer encoder ticks than the profile says.
        factor = speed_factor([s.requested for s in usable], [s.measured for s in usable])
        doc["maps"] = {"ticks_per_mm": round(maps.ticks_per_mm / factor, 3)}
        top = min(mech.max_speed_mm_s, high)
        bottom = min(max(mech.min_speed_mm_s, low), top)
        mechanics["max_speed_mm_s"] = round(top, 3)
        mechanics["min_speed_mm_s"] = round(bottom, 3)
        mechanics["default_speed_mm_s"] = round(min(max(mech.default_speed_mm_s, bottom), top), 3)
    if stroke_mm is not None and abs(stroke_mm - mech.stroke_mm) > 0.05:
        mechanics["stroke_mm"] = round(stroke_mm, 3)
    if mechanics:
        doc["mechanics"] = mechanics
    return doc
