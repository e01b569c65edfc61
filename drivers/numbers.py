"""The one finite-number and range check of the library.

Every number that reaches a device, a timer or a wire format passes here first. Copies of this check drifted
apart before (one missed ``OverflowError`` from ``float(10**400)``, another let ``nan`` through a range test,
because every comparison with ``nan`` is false): keep the rule in this one place and call it.
"""

from __future__ import annotations

import math
from typing import Any

from .errors import GripperError, LimitError


def finite(
    value: Any,
    name: str,
    *,
    low: float | None = None,
    high: float | None = None,
    device: str | None = None,
    command: str | None = None,
    error: type[GripperError] = LimitError,
) -> float:
    """``value`` as a finite float within ``[low, high]`` (each bound optional), or ``error`` naming ``name``.

    Booleans are refused: ``True`` is an ``int`` to Python but never a width or a speed a user meant.
    """
    if isinstance(value, bool):
        raise error(f"{name} must be a number, not {value!r}", device=device, command=command)
    try:
        number = float(value)
    except OverflowError:  # float(10**400)
        raise error(f"{name} is too large: {_short(value)}", device=device, command=command) from None
    except (TypeError, ValueError):
        raise error(f"{name} must be a number, not {_short(value)}", device=device, command=command) from None
    if not math.isfinite(number):
        raise error(f"{name} must be a finite number, not {value!r}", device=device, command=command)
    if (low is not None and number < low) or (high is not None and number > high):
        side = f"below {_num(low)}" if low is not None and number < low else f"above {_num(high)}"
        allowed = f" (allowed: {_num(low)}..{_num(high)})" if low is not None and high is not None else ""
        raise error(f"{name} {_num(number)} is {side}{allowed}", device=device, command=command)
    return number


def _num(value: float | None) -> str:
    """A number as people write it: whole numbers in full (a u32 period of 4294967296 ms read
    "4.29497e+09 is above 4.29497e+09", issue 33 §3), others in their shortest ``g`` form."""
    if value is not None and float(value).is_integer() and abs(value) < 2**53:
        return str(int(value))
    return f"{value:g}"


def _short(value: Any) -> str:
    """A repr that stays readable for a 400-digit integer or a megabyte of text."""
    try:
        text = repr(value)
    except ValueError:  # an int past sys.get_int_max_str_digits()
        return f"an integer of about {value.bit_length() * 0.30103:.0f} digits"
    return text if len(text) <= 40 else f"{text[:30]}... ({len(text)} characters)"
