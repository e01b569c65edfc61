"""The file format of ``grippers record`` and ``grippers plot``: rows of states and command events.

CSV for spreadsheets, JSON Lines for programs; both hold the same rows, and :func:`read` takes either, so a
recording made on a bench machine plots anywhere. Times are seconds since the recording started
(``t_s``); the start's Unix time is in the JSON Lines header and in the CSV's first comment line.
"""

from __future__ import annotations

import csv
import json
from collections.abc import Iterable, Mapping
from pathlib import Path
from typing import Any

RECORD_SCHEMA_ID = "grippers.record/1"
COLUMNS = (
    "t_s",
    "kind",  # "state" or "command"
    "width_mm",
    "speed_mm_s",
    "force_n",
    "current_a",
    "grasp_state",
    "moving",
    "referenced",
    "faults",
    "command",  # the command as given to --do
    "phase",  # start, done, failed
    "detail",  # the result or the error, one line
)
NUMBERS = ("t_s", "width_mm", "speed_mm_s", "force_n", "current_a")
FORMATS = {".csv": "csv", ".jsonl": "jsonl", ".ndjson": "jsonl"}


class RecordingError(ValueError):
    """A file that is not a recording; names the file and the line."""


def format_of(path: str | Path) -> str:
    fmt = FORMATS.get(Path(path).suffix.lower())
    if fmt is None:
        raise RecordingError(f"{path}: the name must end in .csv or .jsonl")
    return fmt


def write(path: str | Path, header: Mapping[str, Any], rows: Iterable[Mapping[str, Any]]) -> None:
    fmt = format_of(path)
    with open(path, "w", newline="", encoding="utf-8") as fh:
        if fmt == "jsonl":
            fh.write(json.dumps({"schema": RECORD_SCHEMA_ID, **header}) + "\n")
            for row in rows:
                fh.write(json.dumps({k: v for k, v in row.items() if v is not None}) + "\n")
            return
        fh.write(f"# {json.dumps({'schema': RECORD_SCHEMA_ID, **header})}\n")
        writer = csv.DictWriter(fh, fieldnames=COLUMNS, extrasaction="ignore")
        writer.writeheader()
        for row in rows:
            out = dict(row)
            if isinstance(out.get("faults"), list):
                out["faults"] = " ".join(out["faults"])
            writer.writerow({k: ("" if out.get(k) is None else out[k]) for k in COLUMNS})


def _number(value: Any) -> float | None:
    if value in (None, ""):
        return None
    return float(value)


def read(path: str | Path) -> tuple[dict[str, Any], list[dict[str, Any]]]:
    """(header, rows) of a recording; numbers as floats, empty cells as None."""
    fmt = format_of(path)
    try:
        text = Path(path).read_text(encoding="utf-8")
    except OSError as exc:
        raise RecordingError(f"{path}: cannot read: {exc.strerror or exc}") from None
    lines = text.splitlines()
    header: dict[str, Any] = {}
    rows: list[dict[str, Any]] = []
    if fmt == "jsonl":
        for number, line in enumerate(lines, start=1):
            if not line.strip():
                continue
            try:
                obj = json.loads(line)
            except json.JSONDecodeError as exc:
                raise RecordingError(f"{path}: line {number}: not JSON: {exc.msg}") from None
            if number == 1 and obj.get("schema") == RECORD_SCHEMA_ID:
                header = obj
            else:
                rows.append(obj)
    else:
        if lines and lines[0].startswith("# "):
            try:
                header = json.loads(lines[0][2:])
            except json.JSONDecodeError:
                header = {}
            lines = lines[1:]
        for number, row in enumerate(csv.DictReader(lines), start=2):
            try:
                rows.append(
                    {
                        **row,
                        **{k: _number(row.get(k)) for k in NUMBERS},
                    }
                )
            except ValueError as exc:
                raise RecordingError(f"{path}: line {number}: {exc}") from None
    if header.get("schema") != RECORD_SCHEMA_ID:
        raise RecordingError(f"{path}: not a grippers recording (no {RECORD_SCHEMA_ID} header)")
    return header, rows
