"""Finger travel as a trapezoidal velocity profile, evaluated at any simulated time.

The model asks "where are the fingers at time t" far more often than it starts a motion (every width/speed
read and auto update), so a motion is planned once as a closed-form profile instead of being integrated in
steps: reads are exact whatever the server's tick or time scale.
"""

from __future__ import annotations

import math
from dataclasses import dataclass


@dataclass(frozen=True, slots=True)
class Trapezoid:
    """Rest-to-rest travel from ``start`` to ``end`` (mm) starting at ``t0`` (s).

    Accelerates with ``accel`` up to ``speed`` (or less when the distance is too short: a triangle), cruises,
    and decelerates with the same magnitude; the WSG manual gives one acceleration for both (§3.3.1).
    """

    t0: float
    start: float
    end: float
    speed: float
    accel: float

    @property
    def distance(self) -> float:
        return abs(self.end - self.start)

    @property
    def direction(self) -> float:
        return 1.0 if self.end >= self.start else -1.0

    def _phases(self) -> tuple[float, float, float]:
        """(acceleration time, cruise time, peak speed)."""
        d = self.distance
        if d <= 0.0:
            return 0.0, 0.0, 0.0
        v, a = self.speed, self.accel
        if d >= v * v / a:
            t_acc = v / a
            return t_acc, (d - v * v / a) / v, v
        t_acc = math.sqrt(d / a)
        return t_acc, 0.0, a * t_acc

    @property
    def duration(self) -> float:
        t_acc, t_cruise, _ = self._phases()
        return 2.0 * t_acc + t_cruise

    @property
    def t_end(self) -> float:
        return self.t0 + self.duration

    def _travelled(self, tau: float) -> float:
        t_acc, t_cruise, v_peak = self._phases()
        a = self.accel
        if tau <= 0.0:
            return 0.0
        if tau < t_acc:
            return 0.5 * a * tau * tau
        s_acc = 0.5 * a * t_acc * t_acc
        if tau < t_acc + t_cruise:
            return s_acc + v_peak * (tau - t_acc)
        td = tau - t_acc - t_cruise
        if td >= t_acc:
            return self.distance
        return min(self.distance, s_acc + v_peak * t_cruise + v_peak * td - 0.5 * a * td * td)

    def position(self, t: float) -> float:
        return self.start + self.direction * self._travelled(t - self.t0)

    def velocity(self, t: float) -> float:
        """Signed velocity (mm/s, positive = opening)."""
        t_acc, t_cruise, v_peak = self._phases()
        tau = t - self.t0
        if tau <= 0.0 or tau >= 2.0 * t_acc + t_cruise:
            return 0.0
        if tau < t_acc:
            v = self.accel * tau
        elif tau < t_acc + t_cruise:
            v = v_peak
        else:
            v = max(0.0, v_peak - self.accel * (tau - t_acc - t_cruise))
        return self.direction * v
