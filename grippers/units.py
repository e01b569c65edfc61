"""Unit conversions: the one place the generic code converts (issue 32 §4, issue 40 §6).

The API speaks SI (m, m/s, A, s); profiles, messages and the CLI speak millimetres and milliamperes, as the
manuals and the people at the bench do, and a few outside formats want milliseconds (Zenoh's lease, the ROS
diagnostics' ages) or nanoseconds (an MCAP log time). The backends convert the device's own units;
everything generic that shows or reads such a number (limits from a profile, an error's "at 31.5 mm", the
CLI's tables and JSON, the panel's commands, a recording's joint states) goes through here, so that a factor
of a thousand is written once. tests/test_readable_tree.py fails on a ``* 1000`` anywhere else in the
generic modules.
"""

from __future__ import annotations

from typing import overload

MM_PER_M = 1000.0
MA_PER_A = 1000.0
MS_PER_S = 1000.0
NS_PER_S = 1_000_000_000


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


@overload
def to_amps(value: float) -> float: ...
@overload
def to_amps(value: None) -> None: ...
def to_amps(value: float | None) -> float | None:
    """Milliamperes (a profile's current limit) as amperes (the API's ``current``); None stays None."""
    return None if value is None else value / MA_PER_A


def to_ms(seconds: float) -> float:
    """Seconds as milliseconds (Zenoh's lease, the ages the ROS node's diagnostics show)."""
    return seconds * MS_PER_S


def to_ns(seconds: float) -> int:
    """Seconds as whole nanoseconds (an MCAP log time), truncated as ``int`` truncates."""
    return int(seconds * NS_PER_S)


def split_ns(stamp_ns: int) -> tuple[int, int]:
    """Nanoseconds as (seconds, nanoseconds within the second), the ROS ``builtin_interfaces/Time`` split."""
    sec, nanosec = divmod(stamp_ns, NS_PER_S)
    return sec, nanosec


def millisecond_of(seconds: float) -> int:
    """The milliseconds within the second of a time (0..999), for a clock reading ``12:03:07.250``."""
    return int(seconds * MS_PER_S) % int(MS_PER_S)
