"""A gripper's link to its device as the user sees it (``connected``, ``on_connection``), and the hooks a
backend implements so that ``reconnect=true`` (grippers/reconnect.py) can bring the link back: apart from
the core of :class:`~grippers.gripper.Gripper`, which it is a mixin of.
"""

from __future__ import annotations

from collections.abc import Callable
from typing import TYPE_CHECKING, Any, Protocol

from .errors import DeviceMismatch, NotSupported
from .parts import GripperPart

if TYPE_CHECKING:
    from .errors import GripperError
    from .states import GripperState


class Policy(Protocol):
    """The reconnection policy a watch follows (grippers/reconnect.py's ReconnectPolicy), as users read it."""

    @property
    def backoff_s(self) -> float: ...

    @property
    def backoff_max_s(self) -> float: ...

    @property
    def heartbeat_s(self) -> float: ...

    @property
    def acknowledge_on_reconnect(self) -> bool: ...


class Watch(Protocol):
    """What the gripper asks of its link watch (grippers/reconnect.py's LinkWatch, set with reconnect=true).

    Declared here, not imported from reconnect.py: the watch builds on the Gripper, so the Gripper names only
    this face of it (issue 32: no import circle between the core and reconnection).
    """

    @property
    def connected(self) -> bool: ...

    def check(self, command: str) -> None: ...

    def add_listener(self, callback: Callable[[bool], Any]) -> Callable[[], None]: ...

    def stream_reader(
        self, read: Callable[[], GripperState], stopped: Callable[[], bool]
    ) -> Callable[[], Any]: ...

    def close(self) -> None: ...

    # Read by users and tests through Gripper.link_watch: what the watch does, never how.
    @property
    def policy(self) -> Policy: ...

    epoch: int
    """Reconnections so far (a stream that saw another epoch missed states)."""
    attempts: int
    """Failed attempts in the current outage."""
    last_error: GripperError | None
    """Why the link was last lost, or the last attempt failed."""


class ConnectionHooks(GripperPart):
    """Connection state for users, reconnection hooks for backends."""

    # Set by Gripper.__init__ (and by grippers/reconnect.py's attach for the last two).
    _closed: bool
    _on_close: list[Callable[[], None]]
    _watch: Watch | None
    _opened_identity: dict[str, str]

    @property
    def link_watch(self) -> Watch | None:
        """With ``reconnect=true``: the watch that brings a lost link back (its ``policy``, ``epoch``: the
        reconnections so far, ``attempts`` in the current outage, ``last_error``); None when reconnection is
        off. Read it; the gripper drives it."""
        return self._watch

    @property
    def connected(self) -> bool:
        """False while a lost link is being re-established (reconnect=true) or after close()."""
        if self._closed:
            return False
        return True if self._watch is None else self._watch.connected

    def on_connection(self, callback: Callable[[bool], Any]) -> Callable[[], None]:
        """Call ``callback(connected)`` from a background thread whenever the link is lost or back; returns
        a function that unregisters it. Without reconnect=true only a loss at close() is reported."""
        if self._watch is not None:
            return self._watch.add_listener(callback)

        def at_close() -> None:
            callback(False)

        self._on_close.append(at_close)

        def remove() -> None:
            if at_close in self._on_close:
                self._on_close.remove(at_close)

        return remove

    # Backends that can re-establish their link override these (reconnect=true).
    def _identity(self) -> dict[str, str]:
        """What tells this device from another of its family (model, serial), read without traffic where
        the backend can. Recorded when reconnection is switched on; empty: devices cannot be told apart."""
        return {}

    def _check_same_device(self, found: dict[str, str]) -> None:
        """Called by a backend's ``_reconnect`` before it swaps a fresh link in: DeviceMismatch when another
        device answers where the opened one was. Refused rather than adopted: the profile, the limits and the
        application's idea of the cell all belong to the opened device (a WSG 25 taking a WSG 50's 70 N
        grasp), so the caller reopens on purpose if the new device is meant."""
        opened = self._opened_identity
        if not opened:
            return
        differs = {k: v for k, v in found.items() if k in opened and opened[k] != v}
        if differs:
            was = ", ".join(f"{k} {opened[k]}" for k in differs)
            now = ", ".join(f"{k} {v}" for k, v in differs.items())
            raise DeviceMismatch(
                f"another device answers here ({now}; opened: {was}): refused, reopen to use it",
                device=self.name,
                command="reconnect",
            )

    def _link_alive(self) -> bool:
        """Cheap, no traffic: whether the driver has noticed its link is gone."""
        return True

    def _reconnect(self) -> None:
        """Open a fresh driver on the same URL and swap it in; GripperError while the device is not back."""
        raise NotSupported("this backend cannot reconnect", device=self.name, command="reconnect")
