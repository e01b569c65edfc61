"""Automatic reconnection (``reconnect=true``): a lost link is re-established in the background.

One :class:`LinkWatch` per gripper, with one thread. While connected it watches the driver (a flag it sets
itself when its transport fails, checked without traffic every :data:`POLL` seconds) and sends a state query
every ``heartbeat_s`` (so a link that died while idle, or a CAN node that went silent, is noticed without a
user call). Once lost, it reopens the driver through the backend's ``_reconnect`` hook with a bounded
exponential backoff (``reconnect_backoff_s`` doubling up to ``reconnect_backoff_max_s``) until it succeeds or
the gripper is closed. Meanwhile every call raises ConnectionLost at once (``Gripper._check_open``): nothing
waits for a device that is not there.

A WSG whose TCP connection dropped without 07h comes back in FAST STOP (manual 4.0.x §1.4.2): the gripper then
refuses motion with FastStopActive until ``acknowledge()``. ``acknowledge_on_reconnect=true`` acknowledges it
automatically; it is off by default because whether the cell is safe to move after an outage is a decision
for the application, not for a library.
"""

from __future__ import annotations

import dataclasses
import logging
import threading
import time
from collections.abc import Callable
from typing import TYPE_CHECKING, Any

from .errors import ConnectionLost, GripperError, GripperTimeout, NotSupported

if TYPE_CHECKING:
    from .gripper import Gripper
    from .settings import Settings
    from .states import GripperState

log = logging.getLogger(__name__)

POLL = 0.02  # s between the no-traffic checks of the driver's own "lost" flag
MISSED_HEARTBEATS = 2  # consecutive heartbeat timeouts that count as a lost link (a silent CAN node)


# The settings from_settings() takes, once the gripper is open: grippers.open expects them before it connects,
# so a misspelt one is refused before any I/O too (Settings.check).
SETTINGS = (
    "reconnect",
    "reconnect_backoff_s",
    "reconnect_backoff_max_s",
    "heartbeat_s",
    "acknowledge_on_reconnect",
)


@dataclasses.dataclass(frozen=True)
class ReconnectPolicy:
    backoff_s: float = 0.1
    backoff_max_s: float = 5.0
    heartbeat_s: float = 0.5
    acknowledge_on_reconnect: bool = False

    @classmethod
    def from_settings(cls, settings: Settings, profile: Any) -> ReconnectPolicy | None:
        """The policy if reconnection is on (keyword > URL query > the profile's [connection] table)."""
        conn = getattr(profile, "connection", None)
        on = settings.bool("reconnect", getattr(conn, "reconnect", False))
        policy = cls(
            backoff_s=settings.positive(
                "reconnect_backoff_s", getattr(conn, "reconnect_backoff_s", cls.backoff_s)
            ),
            backoff_max_s=settings.positive(
                "reconnect_backoff_max_s", getattr(conn, "reconnect_backoff_max_s", cls.backoff_max_s)
            ),
            heartbeat_s=settings.positive("heartbeat_s", getattr(conn, "heartbeat_s", cls.heartbeat_s)),
            acknowledge_on_reconnect=settings.bool(
                "acknowledge_on_reconnect", getattr(conn, "acknowledge_on_reconnect", False)
            ),
        )
        return policy if on else None


class LinkWatch:
    """Connected or not, the listeners to tell, and the thread that brings the link back."""

    def __init__(self, gripper: Gripper, policy: ReconnectPolicy) -> None:
        self._g = gripper
        self.policy = policy
        self._cond = threading.Condition()
        self._connected = True
        self._closed = False
        self.epoch = 0  # bumped at every reconnection: a stream that saw another epoch missed states
        self.attempts = 0  # failed attempts in the current outage
        self.outages = 0
        self.last_error: GripperError | None = None
        self._listeners: list[Callable[[bool], Any]] = []
        name = f"grippers-reconnect {gripper.name}"
        self._thread = threading.Thread(target=self._run, name=name, daemon=True)
        self._thread.start()

    @property
    def connected(self) -> bool:
        return self._connected

    def check(self, command: str) -> None:
        if not self._connected:
            cause = f" ({self.last_error.message})" if self.last_error is not None else ""
            raise ConnectionLost(
                f"link lost{cause}; reconnecting (attempt {self.attempts + 1})",
                device=self._g.name,
                command=command,
            )

    def add_listener(self, callback: Callable[[bool], Any]) -> Callable[[], None]:
        with self._cond:
            self._listeners.append(callback)

        def remove() -> None:
            with self._cond:
                if callback in self._listeners:
                    self._listeners.remove(callback)

        return remove

    def lost(self, error: GripperError | None = None) -> None:
        """Mark the link lost now (a caller saw ConnectionLost): calls fail at once from here on."""
        with self._cond:
            if not self._connected or self._closed:
                return
            self._connected = False
            self.outages += 1
            self.attempts = 0
            self.last_error = error
            self._cond.notify_all()
        log.info("%s: link lost (%s); reconnecting", self._g.name, error)
        # Servoing ends with the link: after the outage the device may stand elsewhere or be in FAST STOP,
        # so streaming targets again is the application's decision (a new servo() call starts it).
        self._g._servo.end(stop_device=False)
        self._tell(False)

    def wait_connected(self, timeout: float) -> bool:
        with self._cond:
            return self._cond.wait_for(lambda: self._connected or self._closed, timeout) and self._connected

    def _tell(self, up: bool) -> None:
        with self._cond:
            listeners = list(self._listeners)
        for fn in listeners:
            try:
                fn(up)
            except Exception:  # a bug in a user's callback must not stop the reconnection
                log.exception("on_connection callback raised")

    # -- the thread -----------------------------------------------------------------------------------------

    def _sleep(self, seconds: float) -> bool:
        """Sleep unless closed; False when closed."""
        with self._cond:
            self._cond.wait_for(lambda: self._closed, seconds)
            return not self._closed

    def _run(self) -> None:
        next_beat = time.monotonic() + self.policy.heartbeat_s
        missed = 0
        while not self._closed:
            if self._connected:
                if not self._sleep(POLL):
                    return
                if not self._connected:
                    continue
                r = self._g.device.reconnection
                if r is not None and not r.alive():
                    self.lost(ConnectionLost("the driver lost its link", device=self._g.name))
                    continue
                if time.monotonic() < next_beat:
                    continue
                next_beat = time.monotonic() + self.policy.heartbeat_s
                try:
                    self._g.device.read_state()
                    missed = 0
                except ConnectionLost as exc:
                    self.lost(exc)
                except GripperTimeout as exc:
                    missed += 1
                    if missed >= MISSED_HEARTBEATS:
                        missed = 0
                        self.lost(exc)
                except GripperError:
                    pass  # the device answered: the link is there
                except Exception:  # noqa: BLE001 - a transport bug: treat as a lost link, try a fresh one
                    log.exception("heartbeat failed")
                    self.lost(ConnectionLost("heartbeat failed", device=self._g.name))
            else:
                self._bring_back()
                next_beat = time.monotonic() + self.policy.heartbeat_s

    def _bring_back(self) -> None:
        delay = self.policy.backoff_s
        while not self._closed:
            try:
                self._g._reconnect()
                if self.policy.acknowledge_on_reconnect and self._g._latch.active:
                    self._g.device.acknowledge()
                    self._g._latch.active = False
            except GripperError as exc:
                self.last_error = exc
            except Exception as exc:  # noqa: BLE001 - an OSError from a transport that is not back yet
                self.last_error = ConnectionLost(f"{type(exc).__name__}: {exc}", device=self._g.name)
            else:
                with self._cond:
                    if self._closed:
                        return
                    self._connected = True
                    self.epoch += 1
                    self._cond.notify_all()
                log.info("%s: link back after %d attempt(s)", self._g.name, self.attempts + 1)
                self._tell(True)
                return
            self.attempts += 1
            if not self._sleep(delay):
                return
            delay = min(delay * 2, self.policy.backoff_max_s)

    def stream_reader(
        self, read: Callable[[], GripperState], stopped: Callable[[], bool]
    ) -> Callable[[], Any]:
        """``read`` for a state stream that survives outages: during one it waits (until the link is back,
        the stream is stopped or the gripper closed); the first state after it has ``gap`` set."""
        seen = self.epoch

        def reader() -> GripperState:
            nonlocal seen
            while True:
                if not self._connected:
                    while not self.wait_connected(0.1):
                        if self._closed or stopped():
                            raise ConnectionLost(
                                "closed during an outage", device=self._g.name, command="stream"
                            )
                try:
                    state = read()
                except ConnectionLost as exc:
                    self.lost(exc)
                    continue
                if self.epoch != seen:
                    seen = self.epoch
                    return dataclasses.replace(state, gap=True)
                return state

        return reader

    def close(self) -> None:
        with self._cond:
            self._closed = True
            was = self._connected
            self._connected = False
            self._cond.notify_all()
        if threading.current_thread() is not self._thread:
            self._thread.join(5.0)
        if was:
            self._tell(False)


def attach(gripper: Gripper, settings: Settings) -> None:
    """Switch reconnection on for ``gripper`` if the settings (or its profile) ask for it; a device that
    offers no reconnection refuses it here, at open, instead of a watch that can never reconnect."""
    policy = ReconnectPolicy.from_settings(settings, gripper.profile)
    if policy is None:
        return
    r = gripper.device.reconnection
    if r is None:
        raise NotSupported("this device cannot reconnect", device=gripper.name, command="open")
    gripper._link.opened_identity = r.identity()  # a device that comes back must be this one
    gripper._link.watch = LinkWatch(gripper, policy)
