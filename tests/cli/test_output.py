"""Formatting helpers: firmware strings, units, tables, one-line errors."""

from __future__ import annotations

import enum
import io
from dataclasses import dataclass

from grippers.cli.output import Progress, error_line, fmt_firmware, fmt_num, table, to_plain


def test_firmware_is_major_minor1_minor2() -> None:
    assert fmt_firmware((4, 0, 2, 1)) == "4.0.2"
    assert fmt_firmware([2, 2]) == "2.2.0"
    assert fmt_firmware("4.0.2") == "4.0.2"
    assert fmt_firmware(None) is None


def test_units_and_missing_values() -> None:
    assert fmt_num(40.0, "mm") == "40.0 mm"
    assert fmt_num(None, "mm") == "-"
    assert fmt_num(float("nan"), "N") == "-"


def test_table_aligns_columns() -> None:
    text = table([["a", 1], ["bbb", None]], ["X", "Y"])
    lines = text.splitlines()
    assert lines[0].startswith("X    Y") and lines[3] == "bbb  -"


def test_to_plain_handles_enums_dataclasses_and_nan() -> None:
    class Grasp(enum.IntEnum):
        HOLDING = 3

    @dataclass
    class S:
        width: float
        grasp: Grasp

    assert to_plain(S(float("nan"), Grasp.HOLDING)) == {"width": None, "grasp": "holding"}


def test_error_line_is_one_line() -> None:
    assert error_line("probe", ValueError("a\nb")) == "grippers probe: error: a b"


def test_progress_is_silent_when_not_a_tty() -> None:
    out = io.StringIO()
    p = Progress(out)
    p.update("probing")
    p.done()
    assert out.getvalue() == ""
