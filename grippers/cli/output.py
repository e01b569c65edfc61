"""Formatting for the command line: tables, units, JSON documents, progress and one-line errors.

Kept free of heavy imports (no python-can, pydantic or drivers) because every subcommand imports it and
``grippers --help`` has a start-up budget. The JSON documents written here are the CLI's stable contract
with programs; their schemas are in ``docs/cli.md`` and :data:`SCHEMAS`.
"""

from __future__ import annotations

import enum
import json
import math
import re
import sys
from collections.abc import Iterable, Mapping, Sequence
from typing import TYPE_CHECKING, Any, TextIO, overload

from grippers.units import to_m, to_mm

if TYPE_CHECKING:
    from grippers.profile_model import Limits
    from grippers.states import DeviceInfo, GripperState

# Exit codes (docs/cli.md): 0 success / a gripper found, 1 nothing answered, not a gripper or the device
# failed the command, 2 usage errors (argparse uses 2 as well), 130 interrupted.
EXIT_OK = 0
EXIT_FAILED = 1
EXIT_USAGE = 2
EXIT_INTERRUPTED = 130

PROBE_SCHEMA_ID = "grippers.probe/2"
STATE_SCHEMA_ID = "grippers.state/2"
INFO_SCHEMA_ID = "grippers.info/1"
RESULT_SCHEMA_ID = "grippers.result/2"
MONITOR_SCHEMA_ID = "grippers.monitor/1"
PROFILES_SCHEMA_ID = "grippers.profiles/1"
SETTINGS_SCHEMA_ID = "grippers.settings/1"
DOCTOR_SCHEMA_ID = "grippers.doctor/1"


class UsageError(Exception):
    """A command line that cannot be carried out as written (malformed URL, bad number): exit code 2."""


# --- units -------------------------------------------------------------------------------------------------


# The API speaks SI (metres, m/s); people and the CLI speak millimetres. Every command converts here, once
# each way (issue 32 §4: the CLI's display units in one module), so a width, a speed and a tolerance read the
# same in every command; None (the device did not say) stays None.


@overload
def m_to_mm(value: float) -> float: ...
@overload
def m_to_mm(value: None) -> None: ...
def m_to_mm(value: float | None) -> float | None:
    """Metres (or m/s) as millimetres (mm/s)."""
    return to_mm(value)


@overload
def mm_to_m(value: float) -> float: ...
@overload
def mm_to_m(value: None) -> None: ...
def mm_to_m(value: float | None) -> float | None:
    """Millimetres (mm/s) as metres (m/s), for the API."""
    return to_m(value)


def fmt_num(value: float | None, unit: str = "", digits: int = 1) -> str:
    """A number with its unit, or '-' when the device did not say."""
    if value is None or (isinstance(value, float) and math.isnan(value)):
        return "-"
    text = f"{value:.{digits}f}"
    return f"{text} {unit}" if unit else text


def fmt_firmware(version: Any) -> str | None:
    """Firmware as ``major.minor1.minor2``, the WSG's 50h form (WSG manual 4.0.x §3.5.1), for every family.

    A release-candidate suffix (``4.0.1-rc2``) is dropped here (``info`` keeps it in ``extra``); a device
    that reports one number (the MSG's software version byte) shows as ``N.0.0``, so programs parse one form.
    """
    if version is None:
        return None
    if isinstance(version, int):
        return f"{version}.0.0"
    if isinstance(version, Sequence) and not isinstance(version, str):
        parts = [int(p) for p in list(version)[:3]]
        while len(parts) < 3:
            parts.append(0)
        return ".".join(str(p) for p in parts)
    if not isinstance(version, str):
        for names in (("major", "minor1", "minor2"), ("major", "minor", "patch")):
            if all(hasattr(version, n) for n in names):
                return ".".join(str(int(getattr(version, n))) for n in names)
        version = str(version)
    m = re.match(r"^\s*v?(\d+)(?:\.(\d+))?(?:\.(\d+))?", version)
    if m is None:
        return None
    return ".".join(str(int(g or 0)) for g in m.groups())


# --- plain data out of API objects --------------------------------------------------------------------------


def to_plain(value: Any) -> Any:
    """Turn dataclasses, pydantic models, enums and tuples into JSON-able values without importing them."""
    if isinstance(value, enum.Enum):  # before int: IntEnum members are ints
        return value.name.lower()
    if value is None or isinstance(value, bool | int | str):
        return value
    if isinstance(value, float):
        return None if math.isnan(value) or math.isinf(value) else value
    if isinstance(value, Mapping):
        return {str(k): to_plain(v) for k, v in value.items()}
    if isinstance(value, bytes | bytearray):
        return value.hex()
    if isinstance(value, Iterable):
        return [to_plain(v) for v in value]
    if hasattr(value, "model_dump"):
        return to_plain(value.model_dump())
    if hasattr(value, "__dataclass_fields__"):
        return {k: to_plain(getattr(value, k)) for k in value.__dataclass_fields__}
    return str(value)


def enum_text(value: Any) -> str | None:
    """An enum's lower-case name ('holding'), a string as it is, None as None."""
    if value is None:
        return None
    if isinstance(value, enum.Enum):
        return value.name.lower()
    return str(value)


# --- writers -----------------------------------------------------------------------------------------------


def write_json(document: Mapping[str, Any], stream: TextIO | None = None) -> None:
    """One JSON document per line, so ``--watch --json`` output is JSON Lines."""
    out = stream or sys.stdout
    out.write(json.dumps(to_plain(document), sort_keys=False) + "\n")
    out.flush()


def table(rows: Sequence[Sequence[Any]], headers: Sequence[str]) -> str:
    """A left-aligned text table with a header rule; cells are str()-ed, None shows as '-'."""
    cells = [[("-" if c is None else str(c)) for c in row] for row in rows]
    widths = [len(h) for h in headers]
    for row in cells:
        for i, cell in enumerate(row):
            widths[i] = max(widths[i], len(cell))
    lines = ["  ".join(h.ljust(w) for h, w in zip(headers, widths, strict=True)).rstrip()]
    lines.append("  ".join("-" * w for w in widths))
    for row in cells:
        lines.append("  ".join(c.ljust(w) for c, w in zip(row, widths, strict=True)).rstrip())
    return "\n".join(lines)


def key_values(pairs: Sequence[tuple[str, Any]]) -> str:
    """Aligned ``key: value`` lines for one device."""
    width = max((len(k) for k, _ in pairs), default=0)
    return "\n".join(f"{k + ':':<{width + 1}} {'-' if v is None else v}" for k, v in pairs)


def error_line(command: str | None, exc: BaseException | str) -> str:
    """The single stderr line every failure ends with (no traceback unless --debug)."""
    text = str(exc) if str(exc) else type(exc).__name__
    text = " ".join(text.split())  # a multi-line message still makes one line
    prefix = f"grippers {command}" if command else "grippers"
    return f"{prefix}: error: {text}"


class Progress:
    """Progress notes on stderr, only when stderr is a terminal: pipes and tests see clean output."""

    def __init__(self, stream: TextIO | None = None, enabled: bool | None = None) -> None:
        self._stream = stream or sys.stderr
        self._enabled = self._stream.isatty() if enabled is None else enabled
        self._width = 0

    def update(self, text: str) -> None:
        if not self._enabled:
            return
        text = text[:100]
        pad = max(0, self._width - len(text))
        self._stream.write("\r" + text + " " * pad)
        self._stream.flush()
        self._width = len(text)

    def done(self) -> None:
        if self._enabled and self._width:
            self._stream.write("\r" + " " * self._width + "\r")
            self._stream.flush()
            self._width = 0


# --- API objects to the CLI's plain documents --------------------------------------------------------------
#
# Everything the CLI prints about a gripper, and every row grippers.recorder writes, goes through
# state_dict(), info_dict() and limits_dict(): the JSON schemas in docs/cli.md are produced in one place and
# the API's SI becomes mm, mm/s and N here and nowhere else. Here, not in common.py, so the recorder (API
# layer) does not import the module that opens grippers (issue 32: that was an import circle).


def _mm(value: float | None) -> float | None:
    return None if value is None else round(float(m_to_mm(value) or 0.0), 3)


def _num(value: float | None) -> float | None:
    return None if value is None else round(float(value), 3)


def state_dict(state: GripperState) -> dict[str, Any]:
    """The ``state`` object of the CLI's schemas: width in mm, speed in mm/s, force in N, current in A."""
    return {
        "width_mm": _mm(state.width),
        "speed_mm_s": _mm(state.speed),
        "force_n": _num(state.force),
        "current_a": _num(state.current),
        "grasp_state": state.grasp.value,
        "moving": state.moving,
        "referenced": state.referenced,
        "faults": list(state.faults),
    }


def limits_dict(limits: Limits) -> dict[str, Any]:
    return {
        "min_width_mm": _mm(limits.min_width),
        "max_width_mm": _mm(limits.max_width),
        "min_speed_mm_s": _mm(limits.min_speed),
        "max_speed_mm_s": _mm(limits.max_speed),
        "min_force_n": _num(limits.min_force),
        "max_force_n": _num(limits.max_force),
        "max_current_a": _num(limits.max_current),
    }


def info_dict(info: DeviceInfo) -> dict[str, Any]:
    extra = to_plain(info.extra) or {}
    return {
        "family": info.family,
        "vendor": info.vendor,
        "model": info.model,
        "profile": info.profile,
        # As the API says it, nothing added or cut (issue 22 §1: the MSG's '12' read '12.0.0' here before).
        "firmware": info.firmware,
        "hardware": info.hardware,
        "serial": info.serial,
        "limits": limits_dict(info.limits),
        "extra": extra,
    }
