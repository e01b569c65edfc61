"""A gripper's link to its device as the user sees it (``connected``, ``on_connection``, ``link_watch``):
a collaborator of :class:`~grippers.gripper.Gripper`.

Three sources, the first that applies: the link watch of ``reconnect=true`` (grippers/reconnect.py); the
device's own ``liveness`` feature (``Device.liveness``: a served gripper learns of a lost server from Zenoh's
liveliness, final without reconnection); otherwise the link is up until close().
"""

from __future__ import annotations

from collections.abc import Callable
from typing import TYPE_CHECKING, Any, Protocol

from .device import Device
from .errors import ConnectionLost, DeviceMismatch

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


class LinkState:
    """Connected or not, who to tell, and the identity a reconnection must find again."""

    def __init__(self, name: str, device: Device) -> None:
        self.name = name
        self.device = device
        self.watch: Watch | None = None  # set by grippers/reconnect.py's attach (reconnect=true)
        self.opened_identity: dict[str, str] = {}  # the device's identity when reconnection was switched on
        self.on_close: list[Callable[[], None]] = []  # run at the end of Gripper.close()

    def check(self, command: str) -> None:
        """During an outage, or after the device's own link was lost for good: ConnectionLost at once."""
        if self.watch is not None:
            self.watch.check(command)
        elif self.device.liveness is not None and self.device.liveness.error is not None:
            raise ConnectionLost(self.device.liveness.error.message, device=self.name, command=command)

    def connected(self, closed: bool) -> bool:
        if closed:
            return False
        if self.watch is not None:
            return self.watch.connected
        return self.device.liveness is None or self.device.liveness.error is None

    def on_connection(self, callback: Callable[[bool], Any]) -> Callable[[], None]:
        if self.watch is not None:
            return self.watch.add_listener(callback)
        told: list[bool] = []

        def once(up: bool) -> None:  # a link lost for good is told once, not again at close()
            if not told:
                told.append(up)
                callback(up)

        def at_close() -> None:
            once(False)

        self.on_close.append(at_close)
        unlink = None if self.device.liveness is None else self.device.liveness.add_listener(once)

        def remove() -> None:
            if at_close in self.on_close:
                self.on_close.remove(at_close)
            if unlink is not None:
                unlink()

        return remove

    def check_same_device(self, found: dict[str, str]) -> None:
        """Called by a device's reconnection before it swaps a fresh link in: DeviceMismatch when another
        device answers where the opened one was. Refused rather than adopted: the profile, the limits and the
        application's idea of the cell all belong to the opened device (a WSG 25 taking a WSG 50's 70 N
        grasp), so the caller reopens on purpose if the new device is meant."""
        opened = self.opened_identity
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
