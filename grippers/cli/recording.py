"""The file formats of ``grippers record`` and ``grippers plot``: rows of states and command events.

CSV for spreadsheets, JSON Lines for programs, MCAP for ROS 2 tools and Foxglove
(grippers/cli/recording_mcap.py); all hold the same rows, and :func:`read` takes any of them, so a
recording made on a bench machine plots anywhere. Times are seconds since the recording started (``t_s``).

The recording's header (schema, target, start time, rate, commands) is the first line of a JSON Lines file
and an MCAP metadata record. A CSV keeps it in a sidecar file, ``FILE.csv.json``, so that the CSV itself
starts with its column names: ``csv.DictReader`` and ``pandas.read_csv`` read it as it is (a ``#`` line
above the header, as written before, was taken for the column names by both). :func:`read` still takes
such older files.

A file is opened by :func:`open_sink` before the gripper moves, so a path that cannot be written fails
before anything happens (issue 23 §3), and everything read back is checked row by row: a malformed file is
a :class:`RecordingError` naming the file and the line, never a traceback.
"""

from __future__ import annotations

import csv
import json
from collections.abc import Iterable, Mapping
from pathlib import Path
from typing import IO, Any

from grippers.drivers.numbers import finite
from grippers.errors import GripperError

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
TEXTS = ("grasp_state", "command", "phase", "detail")
KINDS = ("state", "command")
FORMATS = {".csv": "csv", ".jsonl": "jsonl", ".ndjson": "jsonl", ".mcap": "mcap"}
SIDECAR_SUFFIX = ".json"  # grasp.csv -> grasp.csv.json
MAX_BYTES = 1 << 30  # a recording larger than 1 GiB is not read into memory for a plot


class RecordingError(GripperError, ValueError):
    """A file that is not a recording (or cannot be written); names the file and the line."""


def format_of(path: str | Path) -> str:
    fmt = FORMATS.get(Path(path).suffix.lower())
    if fmt is None:
        raise RecordingError(f"{path}: the name must end in .csv, .jsonl or .mcap")
    return fmt


def sidecar_of(path: str | Path) -> Path:
    return Path(str(path) + SIDECAR_SUFFIX)


class Sink:
    """An output opened now and written once at the end (:meth:`write`), or given up (:meth:`abandon`)."""

    def __init__(self, path: str | Path) -> None:
        self.path = Path(path)
        self.format = format_of(path)
        self.files = [str(self.path)]
        self._mcap: Any = None
        self._fh: IO[str] | None = None
        self._side: IO[str] | None = None
        try:
            if self.format == "mcap":
                from .recording_mcap import McapMissing, McapSink

                try:
                    self._mcap = McapSink(open(self.path, "wb"))  # noqa: SIM115 (closed by write/abandon)
                except McapMissing as exc:
                    raise RecordingError(str(exc)) from None
            else:
                self._fh = open(self.path, "w", newline="", encoding="utf-8")  # noqa: SIM115
                if self.format == "csv":
                    self._side = open(sidecar_of(self.path), "w", encoding="utf-8")  # noqa: SIM115
                    self.files.append(str(sidecar_of(self.path)))
        except OSError as exc:
            self.abandon()
            raise RecordingError(f"{exc.filename or path}: cannot write: {exc.strerror or exc}") from None

    def write(self, header: Mapping[str, Any], rows: Iterable[Mapping[str, Any]]) -> None:
        head = {"schema": RECORD_SCHEMA_ID, **header}
        if self._mcap is not None:
            self._mcap.write(head, rows)
            return
        assert self._fh is not None
        with self._fh as fh:
            if self.format == "jsonl":
                fh.write(json.dumps(head) + "\n")
                for row in rows:
                    fh.write(json.dumps({k: v for k, v in row.items() if v is not None}) + "\n")
                return
            assert self._side is not None
            with self._side as side:
                side.write(json.dumps({**head, "columns": list(COLUMNS)}, indent=2) + "\n")
            writer = csv.DictWriter(fh, fieldnames=COLUMNS, extrasaction="ignore")
            writer.writeheader()
            for row in rows:
                out = dict(row)
                if isinstance(out.get("faults"), list):
                    out["faults"] = " ".join(out["faults"])
                writer.writerow({k: ("" if out.get(k) is None else out[k]) for k in COLUMNS})

    def abandon(self) -> None:
        """Close and remove the files opened for this recording: nothing was recorded (the gripper did not
        open, or Ctrl-C came first), and an empty file would later read as a broken recording."""
        for fh in (self._fh, self._side):
            if fh is not None:
                fh.close()
        if self._mcap is not None:
            self._mcap.abandon()
        for name in self.files:
            Path(name).unlink(missing_ok=True)


def open_sink(path: str | Path) -> Sink:
    """The output of a recording, opened (and created) now: a bad path is found before anything moves."""
    return Sink(path)


def write(path: str | Path, header: Mapping[str, Any], rows: Iterable[Mapping[str, Any]]) -> None:
    open_sink(path).write(header, rows)


# --- reading ------------------------------------------------------------------------------------------------


def _number(value: Any, where: str, key: str) -> float | None:
    if value is None or value == "":
        return None
    if isinstance(value, str):
        value = value.strip()
    return finite(value, f"{where}: {key}", error=RecordingError, text=True)  # a cell of a CSV is text


def _flag(value: Any) -> bool | None:
    if isinstance(value, bool) or value is None:
        return value
    text = str(value).strip().lower()
    return {"true": True, "false": False, "1": True, "0": False}.get(text)


def _row(obj: Any, where: str) -> dict[str, Any]:
    """One row, checked: a mapping, a known kind, a finite time, numbers finite or empty, text as text."""
    if not isinstance(obj, Mapping):
        raise RecordingError(f"{where}: a row must be an object, not {type(obj).__name__}")
    kind = obj.get("kind")
    if kind not in KINDS:
        raise RecordingError(f"{where}: kind must be 'state' or 'command', not {str(kind)[:40]!r}")
    row: dict[str, Any] = {"kind": kind}
    for key in NUMBERS:
        row[key] = _number(obj.get(key), where, key)
    if row["t_s"] is None:
        raise RecordingError(f"{where}: no time (t_s)")
    for key in TEXTS:
        value = obj.get(key)
        if value is not None and not isinstance(value, str | int | float | bool):
            raise RecordingError(f"{where}: {key} must be text")
        row[key] = None if value in (None, "") else str(value)
    row["moving"] = _flag(obj.get("moving"))
    row["referenced"] = _flag(obj.get("referenced"))
    faults = obj.get("faults")
    row["faults"] = faults.split() if isinstance(faults, str) else faults if isinstance(faults, list) else []
    return row


def _read_text(path: str | Path) -> str:
    try:
        p = Path(path)
        if p.stat().st_size > MAX_BYTES:
            raise RecordingError(f"{path}: larger than {MAX_BYTES >> 30} GiB: not a recording to plot")
        return p.read_text(encoding="utf-8")
    except OSError as exc:
        raise RecordingError(f"{path}: cannot read: {exc.strerror or exc}") from None
    except UnicodeDecodeError as exc:
        raise RecordingError(f"{path}: not text (byte {exc.start} is not UTF-8)") from None


def _csv_header(path: str | Path, lines: list[str]) -> tuple[dict[str, Any], list[str]]:
    if lines and lines[0].startswith("# "):  # files written before the sidecar (the header as a comment)
        try:
            header = json.loads(lines[0][2:])
        except json.JSONDecodeError:
            header = {}
        return (header if isinstance(header, dict) else {}), lines[1:]
    side = sidecar_of(path)
    if side.exists():
        try:
            header = json.loads(_read_text(side))
        except json.JSONDecodeError as exc:
            raise RecordingError(f"{side}: not JSON: {exc.msg}") from None
        return (header if isinstance(header, dict) else {}), lines
    # A CSV without its sidecar (copied alone): still a recording if its columns are a recording's.
    first = next(csv.reader(lines[:1]), [])
    return ({"schema": RECORD_SCHEMA_ID} if tuple(first) == COLUMNS else {}), lines


def read(path: str | Path) -> tuple[dict[str, Any], list[dict[str, Any]]]:
    """(header, rows) of a recording; numbers as finite floats, empty cells as None."""
    fmt = format_of(path)
    rows: list[dict[str, Any]] = []
    if fmt == "mcap":
        from .recording_mcap import McapMissing, read_mcap

        try:
            header, raw = read_mcap(path)
        except McapMissing as exc:
            raise RecordingError(str(exc)) from None
        except ValueError as exc:
            raise RecordingError(str(exc)) from None
        rows = [_row(obj, f"{path}: message {n}") for n, obj in enumerate(raw, start=1)]
    elif fmt == "jsonl":
        header = {}
        for number, line in enumerate(_read_text(path).splitlines(), start=1):
            if not line.strip():
                continue
            try:
                obj = json.loads(line)
            except (json.JSONDecodeError, RecursionError) as exc:
                reason = exc.msg if isinstance(exc, json.JSONDecodeError) else "nested too deeply"
                raise RecordingError(f"{path}: line {number}: not JSON: {reason}") from None
            if not header:
                if not (isinstance(obj, dict) and obj.get("schema") == RECORD_SCHEMA_ID):
                    break  # the first line must be the header: refused below, before any row is judged
                header = obj
            else:
                rows.append(_row(obj, f"{path}: line {number}"))
    else:
        header, lines = _csv_header(path, _read_text(path).splitlines())
        try:
            for number, obj in enumerate(csv.DictReader(lines), start=2):
                rows.append(_row(obj, f"{path}: line {number}"))
        except csv.Error as exc:
            raise RecordingError(f"{path}: not CSV: {exc}") from None
    if header.get("schema") != RECORD_SCHEMA_ID:
        raise RecordingError(f"{path}: not a grippers recording (no {RECORD_SCHEMA_ID} header)")
    return header, rows
