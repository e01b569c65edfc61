"""Which of a device's motions is the current one: the supersede rule of the drivers that poll for the end.

A backend that waits for a motion's end by polling (the MSG, the Robotiq) gives every motion it starts, and
every stop, a new number. A wait whose number is no longer the current one ends with the cause recorded by
whatever began the newer epoch ("superseded by a newer motion", "aborted by stop()"), so an older motion is
never reported done when the jaws went on to serve a newer one. One class, so the rule and its words are the
same on every family that needs it.
"""

from __future__ import annotations

import threading

from .errors import CommandFailed


class MotionEpochs:
    """The current motion's number and the cause that ended the older ones; thread-safe."""

    def __init__(self) -> None:
        self._lock = threading.Lock()
        self._current = 0
        self._cause = ""

    def begin(self, cause: str) -> int:
        """A new motion (or stop): the waits of older ones end with ``cause``; returns the new number."""
        with self._lock:
            self._current += 1
            self._cause = cause
            return self._current

    def current(self) -> int:
        """The number of the newest motion (or stop)."""
        with self._lock:
            return self._current

    def check(self, motion: int, *, command: str, device: str) -> None:
        """Return while ``motion`` is current; else raise ``CommandFailed`` ("aborted") naming the cause."""
        with self._lock:
            if motion == self._current:
                return
            cause = self._cause
        raise CommandFailed(f"{command} {cause}", status_name="aborted", device=device, command=command)
