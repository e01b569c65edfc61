"""Which page controls a gripper: one at a time, taken by acting, handed over only by an explicit action.

Pure bookkeeping, no I/O (the session applies it): a page observes until it acts; acting with nobody in
control takes control; another page's action is refused with :class:`~grippers.errors.AccessDenied` naming
who controls, until that page presses "Take control". Stop and fast stop are never refused: any operator may
stop a gripper. A ``zenoh://`` gripper adds the server's lease on top (the session takes it with control).
"""

from __future__ import annotations

import threading
from dataclasses import dataclass

from ..errors import AccessDenied

# Commands any page may send, controlling or not (and recording, which does not act on the device).
ANYONE = frozenset({"stop", "fast_stop", "record"})


@dataclass(frozen=True)
class Page:
    """A connected page: an id the server gave it (never one the page chose) and a label for others."""

    id: str
    label: str


class Control:
    """The controlling page of one gripper."""

    def __init__(self, device: str) -> None:
        self.device = device
        self._lock = threading.Lock()
        self.holder: Page | None = None

    def admit(self, page: Page, command: str) -> bool:
        """May ``page`` send ``command``? Takes free control for an action; True when control changed.
        Raises AccessDenied when another page controls."""
        if command in ANYONE:
            return False
        with self._lock:
            if self.holder is None or command == "take_control":
                changed = self.holder != page
                self.holder = page
                return changed
            if self.holder.id == page.id:
                return False
            holder = self.holder.label
        raise AccessDenied(
            f"{command} refused: {holder} controls this gripper; press Take control to act from this page",
            holder=holder,
            device=self.device,
            command=command,
        )

    def leave(self, page: Page) -> bool:
        """The page is gone; True when it was the one in control (then nobody is)."""
        with self._lock:
            if self.holder is not None and self.holder.id == page.id:
                self.holder = None
                return True
            return False
