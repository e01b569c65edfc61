"""Recording from user code: :func:`record` (a :class:`Recorder`) samples one or several grippers into one
file while the program runs, as ``grippers record`` does from the command line (which uses it).

    with grippers.open("sim://wsg50") as left, grippers.open("sim://msg-150") as right:
        with grippers.record("run.csv", {"left": left, "right": right}, rate_hz=100) as rec:
            with rec.command("grasp 40", gripper="left"):
                left.grasp(0.040, force=20)

The file formats are grippers/recording.py's (CSV, JSON Lines, MCAP), and ``grippers plot`` draws them.

Why a writer thread: the states come from one stream thread per gripper and the commands from the caller's
thread, and a Ctrl-C lands in the caller's thread. If that thread wrote, a Ctrl-C could cut an MCAP record in
half (issue 33 §1: a second Ctrl-C left 233 bytes no reader opened). Here only the writer thread touches the
file; :meth:`Recorder.close` waits for it to finish the file (the summary) however many Ctrl-C come, and if
the program ends without closing, the writer finishes the file when the main thread has ended. Rows are
flushed as they come (MCAP: a chunk at least every :data:`MCAP_FLUSH_S`), so a reader finds every sample
written so far even while the recording runs, or after a crash.
"""

from __future__ import annotations

import contextlib
import queue
import re
import threading
import time
from collections.abc import Iterator, Mapping, Sequence
from pathlib import Path
from typing import TYPE_CHECKING, Any

from .cli.output import state_dict  # the one state-to-row conversion (mm, mm/s, N, A)
from .recording import DEFAULT_NAME, RecordingError, Sink, open_sink

if TYPE_CHECKING:
    from .aio import AsyncGripper
    from .gripper import Gripper, StateStream
    from .states import GripperState

    Recordable = (
        Gripper | AsyncGripper | Mapping[str, Gripper | AsyncGripper] | Sequence[Gripper | AsyncGripper]
    )
    """One gripper, ``{name: gripper}`` or a sequence of them, threaded or asyncio."""

__all__ = ["Recorder", "record"]

NAME = re.compile(r"[A-Za-z][A-Za-z0-9_]{0,63}")  # a CSV value, a ROS topic namespace (/NAME/joint_states)
TEXT_FLUSH_S = 0.0  # CSV and JSON Lines: flushed whenever the writer has caught up
MCAP_FLUSH_S = 0.5  # MCAP: a chunk per flush, so not after every row
CLOSE_BOUND_S = 30.0  # close() waits this long for the writer (a disk that hangs must not hang the program)
_END = object()


def names_of(grippers: Recordable) -> dict[str, Gripper]:
    """``{name: gripper}``: one gripper is ``gripper``, a sequence ``g1``, ``g2``..., a mapping as given.
    An asyncio gripper is recorded through the threaded one it holds (``.sync``; its stream thread samples
    whatever the event loop does)."""
    from .aio import AsyncGripper
    from .gripper import Gripper

    if isinstance(grippers, Gripper | AsyncGripper):
        named = {DEFAULT_NAME: grippers}
    elif isinstance(grippers, Mapping):
        named = dict(grippers)
    else:
        named = {f"g{i}": g for i, g in enumerate(grippers, start=1)}
    if not named:
        raise RecordingError("nothing to record: no gripper given")
    out: dict[str, Gripper] = {}
    for name, g in named.items():
        if not isinstance(name, str) or not NAME.fullmatch(name):
            raise RecordingError(
                f"{name!r}: a gripper's name in a recording is a letter, then letters, digits or _ "
                "(it becomes a CSV value and a ROS topic namespace)"
            )
        if isinstance(g, AsyncGripper):
            g = g.sync
        if not isinstance(g, Gripper):
            raise RecordingError(f"{name}: not a Gripper but {type(g).__name__}")
        out[name] = g
    return out


class Recorder:
    """States of one or several grippers, and the commands around them, into one file (:func:`record`).

    Rows go to the file as they come; :meth:`close` (or leaving ``with``) finishes it. Does not open or
    close the grippers: they are the caller's. A write error (a full disk, a file-size limit) ends the
    recording, not the program: :attr:`error` says it (naming the file) and :meth:`close` raises it.
    """

    def __init__(
        self,
        path: str | Path,
        grippers: Gripper
        | AsyncGripper
        | Mapping[str, Gripper | AsyncGripper]
        | Sequence[Gripper | AsyncGripper],
        *,
        rate_hz: float = 50.0,
        header: Mapping[str, Any] | None = None,
        sink: Sink | None = None,
    ) -> None:
        self.grippers = names_of(grippers)
        # ``sink``: an output opened already with open_sink(), as the CLI does before it opens the grippers
        self._sink: Sink = sink if sink is not None else open_sink(path)
        self.path = str(self._sink.path)
        self.format: str = self._sink.format
        self.files: list[str] = list(self._sink.files)
        self.states = 0
        self.events = 0
        self._queue: queue.Queue[Any] = queue.Queue()
        self._count = threading.Lock()
        self._closed = False
        self._finished = threading.Event()  # set by the writer when the file is closed
        self._begun = threading.Event()  # set by the writer once the header is written and the file placed
        self.start = time.time()
        head = {
            "grippers": [{"name": n, "target": str(g.url)} for n, g in self.grippers.items()],
            "start_unix": self.start,
            "rate_hz": rate_hz,
            **(header or {}),
        }
        self._writer = threading.Thread(target=self._write, args=(head,), name="grippers-recorder")
        self._writer.start()  # not a daemon: the interpreter waits for it to finish the file
        self._streams: list[StateStream] = []
        try:
            # The file has its name once this returns (the sink writes under a temporary one until then):
            # a reader that opens it at once finds the header (bounded: a disk that hangs).
            self._begun.wait(CLOSE_BOUND_S)
            for name, g in self.grippers.items():
                self._streams.append(g.stream(rate_hz, callback=self._sampler(name)))
        except BaseException:
            self.close()
            raise

    # -- rows in ------------------------------------------------------------------------------------------

    def _sampler(self, name: str) -> Any:
        def sample(state: GripperState) -> None:
            row = {"t_s": round(state.timestamp - self.start, 6), "gripper": name, "kind": "state"}
            self._put({**row, **state_dict(state)}, state=True)

        return sample

    def _put(self, row: dict[str, Any], *, state: bool) -> None:
        if self._closed:
            return
        with self._count:
            if state:
                self.states += 1
            else:
                self.events += 1
        self._queue.put(row)

    def event(self, command: str, phase: str, detail: str | None = None, gripper: str | None = None) -> None:
        """A command row stamped now: ``phase`` is ``start``, ``done`` or ``failed``; ``gripper`` None: all
        of them (or none, as for a wait)."""
        if gripper is not None and gripper not in self.grippers:
            known = ", ".join(self.grippers)
            raise RecordingError(f"{gripper!r}: not a gripper of this recording ({known})")
        row = {
            "t_s": round(time.time() - self.start, 6),
            "gripper": gripper,
            "kind": "command",
            "command": command,
            "phase": phase,
            "detail": None if detail is None else " ".join(str(detail).split()),
        }
        self._put(row, state=False)

    @contextlib.contextmanager
    def command(self, text: str, gripper: str | None = None) -> Iterator[None]:
        """Stamp ``text``'s start, then its end (``done``) or its error (``failed``, re-raised)."""
        self.event(text, "start", gripper=gripper)
        try:
            yield
        except BaseException as exc:
            self.event(text, "failed", str(exc) or type(exc).__name__, gripper=gripper)
            raise
        self.event(text, "done", gripper=gripper)

    # -- the writer ---------------------------------------------------------------------------------------

    @property
    def error(self) -> RecordingError | None:
        """The write error that ended the recording (naming the file), if one did."""
        return self._sink.error

    def _write(self, head: dict[str, Any]) -> None:
        sink = self._sink
        every = MCAP_FLUSH_S if self.format == "mcap" else TEXT_FLUSH_S
        flushed, dirty = time.monotonic(), False
        main = threading.main_thread()
        try:
            try:
                sink.begin(head)
            finally:
                self._begun.set()
            while True:
                try:
                    item = self._queue.get(timeout=0.2)
                except queue.Empty:
                    item = None
                if item is not None and item is not _END:
                    sink.add(item)
                    dirty = True
                if item is _END or not main.is_alive():  # close(), or the program ended without it
                    break
                if dirty and self._queue.empty() and time.monotonic() - flushed >= every:
                    sink.flush()
                    flushed, dirty = time.monotonic(), False
            while True:  # rows put before the end
                try:
                    item = self._queue.get_nowait()
                except queue.Empty:
                    break
                if item is not _END:
                    sink.add(item)
        finally:
            try:
                sink.close()
            finally:
                self._finished.set()

    # -- the end ------------------------------------------------------------------------------------------

    def close(self) -> None:
        """Stop sampling, finish the file, raise the write error if there was one. Idempotent.

        Ctrl-C while closing does not cut the file: the wait for the writer goes on (bounded) and the
        interrupt is raised after it."""
        interrupted: BaseException | None = None
        for s in self._streams:
            try:
                s.close()
            except KeyboardInterrupt as exc:
                interrupted = exc
        self._closed = True
        self._queue.put(_END)
        # An Event, not Thread.join(): a join interrupted by Ctrl-C can mark a running thread stopped
        # (CPython's bpo-45274 handling), and the wait would end before the file is finished.
        deadline = time.monotonic() + CLOSE_BOUND_S
        while not self._finished.is_set() and time.monotonic() < deadline:
            try:
                self._finished.wait(min(0.2, max(0.0, deadline - time.monotonic())))
            except KeyboardInterrupt as exc:
                interrupted = exc
        if interrupted is not None:
            raise interrupted
        if not self._finished.is_set():
            raise RecordingError(f"{self.path}: the file was not finished within {CLOSE_BOUND_S:g} s")
        if self.error is not None:
            self._count_the_file()
            raise self.error

    def _count_the_file(self) -> None:
        """After a write error, :attr:`states` and :attr:`events` say what the file holds, not what was
        sampled (issue 43 §9: "recorded 450 states" with 231 in the file after a full disk): the rows read
        back, else those known to have reached it at the last flush."""
        from .recording import load

        try:
            rows = load(self.path).rows
        except (RecordingError, OSError):
            counts = self._sink.flushed
            self.states, self.events = counts.get("state", 0), counts.get("command", 0)
            return
        self.states = sum(1 for r in rows if r["kind"] == "state")
        self.events = sum(1 for r in rows if r["kind"] == "command")

    def __enter__(self) -> Recorder:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()

    def __repr__(self) -> str:
        return f"<Recorder {self.path} {', '.join(self.grippers)}{' closed' if self._closed else ''}>"


def record(
    path: str | Path,
    grippers: Gripper
    | AsyncGripper
    | Mapping[str, Gripper | AsyncGripper]
    | Sequence[Gripper | AsyncGripper],
    *,
    rate_hz: float = 50.0,
) -> Recorder:
    """Start recording ``grippers`` to ``path`` (``.csv``, ``.jsonl`` or ``.mcap``, the last with
    ``pip install 'grippers[record]'``); use it in ``with`` or call ``close()``.

    ``grippers`` is one :class:`~grippers.Gripper` or :class:`~grippers.aio.AsyncGripper` (named ``gripper``
    in the file), a mapping
    ``{"left": g1, "right": g2}``, or a sequence (named ``g1``, ``g2``, ...). States are sampled at
    ``rate_hz`` each; :meth:`Recorder.command` marks what the program does. Raises
    :class:`~grippers.recording.RecordingError` (a :class:`~grippers.GripperError`) for a path that cannot
    be written or a name that is not one, before anything is sampled.
    """
    return Recorder(path, grippers, rate_hz=rate_hz)
