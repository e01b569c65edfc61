"""Millimetres and metres: the one place the generic code converts (issue 32 §4).

The API speaks SI (m, m/s); profiles, messages and the CLI speak millimetres, as the manuals and the people
at the bench do. The backends convert the device's own units; everything generic that shows or reads a
millimetre (limits from a profile, an error's "at 31.5 mm", the CLI's tables and JSON) goes through here.
"""

from __future__ import annotations

from typing import overload

MM_PER_M = 1000.0


@overload
def to_mm(value: float) -> float: ...
@overload
def to_mm(value: None) -> None: ...
def to_mm(value: float | None) -> float | None:
    """Metres (or m/s) as millimetres (mm/s); None stays None (a value the device does not report)."""
    return None if value is None else value * MM_PER_M


@overload
def to_m(value: float) -> float: ...
@overload
def to_m(value: None) -> None: ...
def to_m(value: float | None) -> float | None:
    """Millimetres (or mm/s) as metres (m/s); None stays None."""
    return None if value is None else value / MM_PER_M
