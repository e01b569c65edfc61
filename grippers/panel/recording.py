"""The page's Record toggle: the project's own recorder (grippers/recorder.py), to CSV and MCAP at once.

Both files are written while the recording runs (one :class:`~grippers.recorder.Recorder` each, the same
rows), so the page offers either for download once it ends without converting anything. Files live in the
panel's own temporary folder and are named by the server, never by the page.
"""

from __future__ import annotations

import re
import threading
import time
from pathlib import Path

from ..gripper import Gripper
from ..recorder import Recorder

FORMATS = ("csv", "mcap")
RATE_HZ = 50.0


def recorded_name(name: str) -> str:
    """The panel's name as a recording names a gripper (a letter, then letters, digits or ``_``)."""
    text = re.sub(r"[^A-Za-z0-9_]", "_", name)[:63]
    return text if text[:1].isalpha() else f"g{text}"[:64]


class PanelRecording:
    """At most one recording of one gripper at a time; the files of the last one stay downloadable."""

    def __init__(self, name: str, gripper: Gripper, folder: Path) -> None:
        self.name = name
        self.gripper = gripper
        self.folder = folder
        self._lock = threading.Lock()
        self._recorders: list[Recorder] = []
        self._files: dict[str, Path] = {}
        self._count = 0

    @property
    def running(self) -> bool:
        return bool(self._recorders)

    @property
    def downloads(self) -> dict[str, str] | None:
        """``{"csv": FILE NAME, "mcap": ...}`` of the last finished recording."""
        if self._recorders or not self._files:
            return None
        return {fmt: path.name for fmt, path in self._files.items()}

    def start(self) -> None:
        with self._lock:
            if self._recorders:
                return
            self._count += 1
            stem = f"{recorded_name(self.name)}-{time.strftime('%Y%m%d-%H%M%S')}-{self._count}"
            grippers = {recorded_name(self.name): self.gripper}
            try:
                for fmt in FORMATS:
                    self._recorders.append(Recorder(self.folder / f"{stem}.{fmt}", grippers, rate_hz=RATE_HZ))
            except BaseException:
                self._close_all()
                raise
            self._files = {}

    def stop(self) -> None:
        with self._lock:
            if self._recorders:
                self._files = {fmt: Path(r.path) for fmt, r in zip(FORMATS, self._recorders, strict=False)}
            self._close_all()

    def _close_all(self) -> None:
        recorders, self._recorders = self._recorders, []
        error: BaseException | None = None
        for r in recorders:
            try:
                r.close()
            except BaseException as exc:  # the other file is still finished
                error = error or exc
        if error is not None:
            raise error

    def file(self, fmt: str) -> Path | None:
        path = self._files.get(fmt)
        return path if path is not None and not self._recorders and path.is_file() else None

    def close(self) -> None:
        try:
            self.stop()
        except Exception:
            pass

    def __repr__(self) -> str:
        return f"<PanelRecording {self.name}{' running' if self.running else ''}>"


__all__ = ["FORMATS", "PanelRecording", "recorded_name"]
