"""The file formats of recordings (``grippers record``, :func:`grippers.record`, ``grippers plot``): rows of
states and command events, one or several grippers in one file.

CSV for spreadsheets, JSON Lines for programs, MCAP for ROS 2 tools and Foxglove
(grippers/recording_mcap.py); all hold the same rows, and :func:`read` takes any of them, so a recording
made on a bench machine plots anywhere. Times are seconds since the recording started (``t_s``); the
``gripper`` column names the gripper a row belongs to (``gripper`` when one was recorded, else the names the
user gave), so several grippers share one file and one time axis.

The recording's header (schema, grippers and their targets, start time, rate, commands) is the first line of
a JSON Lines file and an MCAP metadata record. A CSV keeps it in a sidecar file, ``FILE.csv.json``, so that
the CSV itself starts with its column names: ``csv.DictReader`` and ``pandas.read_csv`` read it as it is.
:func:`read` still takes older files (``grippers.record/1``: no ``gripper`` column, or a ``#`` header line).

Rows are written as they come (:class:`Sink`: the header at :meth:`Sink.begin`, then :meth:`Sink.add` and
:meth:`Sink.flush`), not at the end (issue 33 §1): a reader always finds every row flushed so far, a full
disk loses only what came after it, and the error names the file. A file cut short (a crash, a full disk)
is read up to its last complete row, and :func:`load` says that it was cut (``Recording.cut``) instead of
refusing it whole. A file is opened by :func:`open_sink` before the gripper moves, so a path that cannot be
written fails before anything happens (issue 23 §3), and everything read back is checked row by row: a
malformed file is a :class:`RecordingError` naming the file and the line, never a traceback.
"""

from __future__ import annotations

import csv
import json
import os
from collections.abc import Mapping
from dataclasses import dataclass
from pathlib import Path
from typing import IO, Any

from grippers.drivers.numbers import finite
from grippers.errors import GripperError

RECORD_SCHEMA_ID = "grippers.record/2"
READABLE_SCHEMAS = ("grippers.record/1", RECORD_SCHEMA_ID)  # /1: one gripper, no gripper column
COLUMNS = (
    "t_s",
    "gripper",  # the gripper's name in this recording
    "kind",  # "state" or "command"
    "width_mm",
    "speed_mm_s",
    "force_n",
    "current_a",
    "grasp_state",
    "moving",
    "referenced",
    "faults",
    "command",  # the command as given to --do (or to Recorder.command)
    "phase",  # start, done, failed
    "detail",  # the result or the error, one line
)
COLUMNS_1 = tuple(c for c in COLUMNS if c != "gripper")  # grippers.record/1
NUMBERS = ("t_s", "width_mm", "speed_mm_s", "force_n", "current_a")
TEXTS = ("gripper", "grasp_state", "command", "phase", "detail")
KINDS = ("state", "command")
FORMATS = {".csv": "csv", ".jsonl": "jsonl", ".ndjson": "jsonl", ".mcap": "mcap"}
SIDECAR_SUFFIX = ".json"  # grasp.csv -> grasp.csv.json
MAX_BYTES = 1 << 30  # a recording larger than 1 GiB is not read into memory for a plot
DEFAULT_NAME = "gripper"  # the gripper column of a recording of one gripper


class RecordingError(GripperError, ValueError):
    """A file that is not a recording, or cannot be written; names the file (and the line)."""


def format_of(path: str | Path) -> str:
    fmt = FORMATS.get(Path(path).suffix.lower())
    if fmt is None:
        raise RecordingError(f"{path}: the name must end in .csv, .jsonl or .mcap")
    return fmt


def sidecar_of(path: str | Path) -> Path:
    return Path(str(path) + SIDECAR_SUFFIX)


def temporary_of(path: str | Path) -> Path:
    """Where a recording is written until it starts: ``.run.csv.<pid>.part`` beside ``run.csv`` (the same
    file system, so moving it into place is one rename)."""
    path = Path(path)
    return path.with_name(f".{path.name}.{os.getpid()}.part")


def _cannot_write(path: str | Path, exc: OSError) -> RecordingError:
    """``run.mcap: cannot write: File too large``: the user's file named, whatever the OS error left out."""
    return RecordingError(f"{path}: cannot write: {exc.strerror or exc}")


class Sink:
    """A recording's files, opened now (a bad path fails before anything moves), then written row by row.

    Written under a temporary name beside the final one (:func:`temporary_of`) until :meth:`begin`, which
    moves the files into place: a run that never starts (the gripper does not open, an unknown profile,
    Ctrl-C first) leaves what the user had under that name untouched (issue 43 §2: an existing ``run.csv``
    and its ``run.csv.json`` were deleted). From :meth:`begin` on the rows go to the final name as they
    come, so a reader finds them while the recording runs (the open file keeps its descriptor across the
    rename).

    Not thread-safe: one thread writes (grippers/recorder.py's writer thread). After a write error every
    call is a no-op but :meth:`close`, which closes what is there; the error is kept in :attr:`error`.
    """

    def __init__(self, path: str | Path) -> None:
        self.path = Path(path)
        self.format = format_of(path)
        self.files = [str(self.path)]
        self.error: RecordingError | None = None
        self.rows = 0
        self.added: dict[str, int] = {}  # rows handed to the file, by kind ("state", "command")
        self.flushed: dict[str, int] = {}  # of those, the ones known to have reached it
        self._temporary = temporary_of(self.path)
        self._placed = False  # moved into place by begin()
        self._mcap: Any = None
        self._fh: IO[str] | None = None
        self._csv: Any = None
        if self.path.is_dir():
            raise RecordingError(f"{path}: cannot write: is a directory")
        try:
            if self.format == "mcap":
                from .recording_mcap import McapMissing, McapSink

                try:
                    self._mcap = McapSink(self._temporary)
                except McapMissing as exc:
                    raise RecordingError(str(exc)) from None
            else:
                self._fh = open(self._temporary, "w", newline="", encoding="utf-8")  # noqa: SIM115 (close())
                if self.format == "csv":
                    sidecar_of(self._temporary).touch()
                    self.files.append(str(sidecar_of(self.path)))
        except OSError as exc:
            self.abandon()
            raise _cannot_write(path, exc) from None

    def _pairs(self) -> list[tuple[Path, Path]]:
        """(temporary, final) for each file of the recording."""
        pairs = [(self._temporary, self.path)]
        if self.format == "csv":
            pairs.append((sidecar_of(self._temporary), sidecar_of(self.path)))
        return pairs

    def _cannot_write(self, exc: OSError) -> RecordingError:
        """The error naming the user's file, never the temporary one."""
        names = {str(t): f for t, f in self._pairs()}
        return _cannot_write(names.get(str(exc.filename), self.path), exc)

    def _place(self) -> None:
        """Move the files into place (the sidecar last: a CSV is read without it)."""
        for temporary, final in self._pairs():
            os.replace(temporary, final)
        self._placed = True

    def _guard(self, what: Any, *args: Any) -> None:
        if self.error is not None:
            return
        try:
            what(*args)
        except OSError as exc:
            self.error = self._cannot_write(exc)
            self._close_quietly()

    def begin(self, header: Mapping[str, Any]) -> None:
        """Write the header (and flush it): from now on the file reads as a recording, if an empty one."""
        self._guard(self._begin, {"schema": RECORD_SCHEMA_ID, **header})

    def _begin(self, head: dict[str, Any]) -> None:
        if self._mcap is not None:
            self._mcap.begin(head)
            self._place()
            return
        assert self._fh is not None
        if self.format == "jsonl":
            self._fh.write(json.dumps(head) + "\n")
        else:
            side = json.dumps({**head, "columns": list(COLUMNS)}, indent=2) + "\n"
            sidecar_of(self._temporary).write_text(side, encoding="utf-8")
            self._csv = csv.DictWriter(self._fh, fieldnames=COLUMNS, extrasaction="ignore")
            self._csv.writeheader()
        self._fh.flush()
        self._place()

    def add(self, row: Mapping[str, Any]) -> None:
        """One row, buffered; :meth:`flush` hands what is buffered to the OS."""
        self._guard(self._add, row)

    def _add(self, row: Mapping[str, Any]) -> None:
        self.rows += 1
        kind = str(row.get("kind"))
        self.added[kind] = self.added.get(kind, 0) + 1
        if self._mcap is not None:
            self._mcap.add(row)
        elif self.format == "jsonl":
            assert self._fh is not None
            self._fh.write(json.dumps({k: v for k, v in row.items() if v is not None}) + "\n")
        else:
            out = dict(row)
            if isinstance(out.get("faults"), list):
                out["faults"] = " ".join(out["faults"])
            self._csv.writerow({k: ("" if out.get(k) is None else out[k]) for k in COLUMNS})

    def flush(self) -> None:
        """Everything added so far reaches the file (MCAP: the chunk in progress is finished)."""
        self._guard(self._mcap.flush if self._mcap is not None else self._flush_text)
        if self.error is None:
            self.flushed = dict(self.added)

    def _flush_text(self) -> None:
        assert self._fh is not None
        self._fh.flush()

    def close(self) -> None:
        """Finish the file (MCAP: the summary and footer) and close it; after an error, close what is
        there."""
        self._guard(self._mcap.finish if self._mcap is not None else self._flush_text)
        if self.error is None:
            self.flushed = dict(self.added)
        self._close_quietly()

    def _close_quietly(self) -> None:
        for close in (
            self._mcap.close if self._mcap is not None else None,
            self._fh.close if self._fh is not None else None,
        ):
            if close is None:
                continue
            try:
                close()
            except OSError as exc:  # the buffer could not be written either: the first error stands
                if self.error is None:
                    self.error = self._cannot_write(exc)

    def abandon(self) -> None:
        """Close and remove the files opened for this recording: nothing was recorded (the gripper did not
        open, or Ctrl-C came first). Before :meth:`begin` only the temporary files go: what the user had
        under the final names stays."""
        self._close_quietly()
        for temporary, final in self._pairs():
            (final if self._placed else temporary).unlink(missing_ok=True)


def open_sink(path: str | Path) -> Sink:
    """The output of a recording, opened (and created) now: a bad path is found before anything moves."""
    return Sink(path)


# --- reading ------------------------------------------------------------------------------------------------


@dataclass
class Recording:
    """What :func:`load` read: the header, the rows in time order, and whether the file was cut short."""

    path: str
    header: dict[str, Any]
    rows: list[dict[str, Any]]
    cut: str | None = None  # why the rest was not read ("the last line is incomplete"), None: whole

    @property
    def grippers(self) -> list[str]:
        """The grippers' names, in the header's order (then any only the rows name)."""
        names = [g.get("name") for g in self.header.get("grippers", []) if isinstance(g, Mapping)]
        out = [str(n) for n in names if n]
        for row in self.rows:
            if row["gripper"] is not None and row["gripper"] not in out:
                out.append(row["gripper"])
        return out


MAX_MAGNITUDE = 1e9  # no time (31 years in s), width, speed, force or current of a recording comes near it


def _number(value: Any, where: str, key: str) -> float | None:
    """A number of a row: finite and within +-MAX_MAGNITUDE (issue 43 §6: a time of 1e308 reached the plot
    as "Singular matrix"); a cell of a CSV is text."""
    if value is None or value == "":
        return None
    if isinstance(value, str):
        value = value.strip()
    if isinstance(value, str) and len(value) > 64:  # no number of ours is written longer (5001 digits: no)
        raise RecordingError(f"{where}: {key} is not a number of a recording ({len(value)} characters)")
    return finite(
        value, f"{where}: {key}", low=-MAX_MAGNITUDE, high=MAX_MAGNITUDE, error=RecordingError, text=True
    )


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
    if row["gripper"] is None and kind == "state":  # grippers.record/1: one gripper, not named
        row["gripper"] = DEFAULT_NAME
    row["moving"] = _flag(obj.get("moving"))
    row["referenced"] = _flag(obj.get("referenced"))
    faults = obj.get("faults")
    row["faults"] = faults.split() if isinstance(faults, str) else faults if isinstance(faults, list) else []
    return row


def _read_text(path: str | Path) -> tuple[str, str | None]:
    """The file's complete lines, and why the rest was left out: a file cut short (a crash, a full disk)
    ends in a line without its newline, which may be a row cut in the middle (``12.3`` of ``12.345``)."""
    try:
        p = Path(path)
        if p.stat().st_size > MAX_BYTES:
            raise RecordingError(f"{path}: larger than {MAX_BYTES >> 30} GiB: not a recording to plot")
        data = p.read_bytes()
    except OSError as exc:
        raise RecordingError(f"{path}: cannot read: {exc.strerror or exc}") from None
    cut = None
    if data and not data.endswith(b"\n"):
        data = data[: data.rfind(b"\n") + 1]
        cut = "its last line is incomplete"
    try:
        return data.decode("utf-8"), cut
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
        text, _ = _read_text(side)
        try:
            header = json.loads(text)
        except json.JSONDecodeError as exc:
            raise RecordingError(f"{side}: not JSON: {exc.msg}") from None
        return (header if isinstance(header, dict) else {}), lines
    # A CSV without its sidecar (copied alone): still a recording if its columns are a recording's.
    first = tuple(next(csv.reader(lines[:1]), []))
    schema = {COLUMNS: RECORD_SCHEMA_ID, COLUMNS_1: READABLE_SCHEMAS[0]}.get(first)
    return ({"schema": schema} if schema else {}), lines


def load(path: str | Path) -> Recording:
    """The recording in ``path`` (CSV, JSON Lines or MCAP), checked row by row, rows in time order.

    A file cut short is read up to its last complete row and says so in ``cut``; anything else that is not
    a recording is a :class:`RecordingError` naming the file and the line."""
    fmt = format_of(path)
    rows: list[dict[str, Any]] = []
    cut: str | None = None
    if fmt == "mcap":
        from .recording_mcap import McapMissing, read_mcap

        try:
            header, raw, cut = read_mcap(path)
        except McapMissing as exc:
            raise RecordingError(str(exc)) from None
        except ValueError as exc:  # read_mcap's own (naming the file), a message no JSON, a number too long
            text = str(exc)
            raise RecordingError(text if text.startswith(f"{path}:") else f"{path}: {text}"[:300]) from None
        rows = [_row(obj, f"{path}: message {n}") for n, obj in enumerate(raw, start=1)]
    elif fmt == "jsonl":
        header = {}
        text, cut = _read_text(path)
        for number, line in enumerate(text.splitlines(), start=1):
            if not line.strip():
                continue
            try:
                obj = json.loads(line)
            except (ValueError, RecursionError) as exc:
                reason = (
                    exc.msg
                    if isinstance(exc, json.JSONDecodeError)
                    else "nested too deeply"
                    if isinstance(exc, RecursionError)
                    else "a number too long"  # Python's int limit (4300 digits): a ValueError of its own
                )
                raise RecordingError(f"{path}: line {number}: not JSON: {reason}") from None
            if not header:
                if not (isinstance(obj, dict) and obj.get("schema") in READABLE_SCHEMAS):
                    break  # the first line must be the header: refused below, before any row is judged
                header = obj
            else:
                rows.append(_row(obj, f"{path}: line {number}"))
    else:
        text, cut = _read_text(path)
        header, lines = _csv_header(path, text.splitlines())
        try:
            for number, obj in enumerate(csv.DictReader(lines), start=2):
                rows.append(_row(obj, f"{path}: line {number}"))
        except csv.Error as exc:
            raise RecordingError(f"{path}: not CSV: {exc}") from None
    if header.get("schema") not in READABLE_SCHEMAS:
        raise RecordingError(f"{path}: not a grippers recording (no {RECORD_SCHEMA_ID} header)")
    # Rows are written as they come, from one thread per gripper: a state read just before a command was
    # stamped may be written just after it. Sorted here (stably), so every reader sees time order.
    rows.sort(key=lambda row: row["t_s"])
    return Recording(str(path), header, rows, cut)


def read(path: str | Path) -> tuple[dict[str, Any], list[dict[str, Any]]]:
    """(header, rows) of a recording: :func:`load` without the note on a file cut short."""
    recording = load(path)
    return recording.header, recording.rows
