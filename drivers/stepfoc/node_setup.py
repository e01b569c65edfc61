"""A STEPFOC node's identity and liveness settings: its id, saved configuration, reset, watchdog and heartbeat
(commands 10-15 and 30, docs/protocols.md §2).

Apart from :class:`~.can_client.StepfocNode` because they are set once, at commissioning or at open, while
the node's class is about status and motion; each is one frame with nothing to match but the ping.
"""

from __future__ import annotations

from abc import abstractmethod
from typing import TYPE_CHECKING, Any, Protocol

from ..errors import GripperTimeout, LimitError
from .can_protocol import MAX_NODE, Cmd, GripperCommand, Watchdog, WatchdogAction

if TYPE_CHECKING:
    import threading


class Heartbeats(Protocol):
    """What the setup asks of the bus a node is on (:class:`~.can_client.StepfocBus` provides it): declared
    here so this mixin does not import the client module that mixes it in (issue 32: no import circles)."""

    def last_heartbeat(self, node: int) -> float | None: ...

    def heartbeat_condition(self, node: int) -> threading.Condition: ...


class NodeSetup:
    """What a node handle offers beyond status and motion (mixed into StepfocNode, which provides these)."""

    bus: Heartbeats
    _node: int
    last_command: GripperCommand | None

    @property
    @abstractmethod
    def device(self) -> str:
        """How errors name this node."""

    @abstractmethod
    def send(self, command: int, value: Any = None, *, remote: bool = False) -> None:
        """One frame, no reply awaited."""

    @abstractmethod
    def _remote(self, command: Cmd, timeout: float | None) -> Any:
        """A remote frame and its reply's value."""

    def ping(self, timeout: float | None = None) -> bool:
        """Remote frame 10; True when the node answers in time, False when it does not."""
        try:
            self._remote(Cmd.PING, timeout)
        except GripperTimeout:
            return False
        return True

    def set_node_id(self, new: int) -> None:
        """Command 11; this handle follows the node to its new id. Lost at reset unless saved (13)."""
        if not isinstance(new, int) or not 0 <= new <= MAX_NODE:
            raise LimitError(f"node {new!r} outside 0..{MAX_NODE}", device=self.device, command="set_can_id")
        self.send(Cmd.SET_CAN_ID, new)
        self._node = new

    def save_config(self) -> None:
        self.send(Cmd.SAVE_CONFIG)

    def reset(self) -> None:
        """Command 14: the driver reboots and loses its calibration (docs/protocols.md §2)."""
        self.send(Cmd.RESET)
        self.last_command = None

    def watchdog(self, ms: int, action: WatchdogAction | int = WatchdogAction.IDLE) -> None:
        """Command 15: the node raises a timeout error if no frame reaches it within ``ms`` (0 = off)."""
        if not 0 <= ms <= 0xFFFFFFFF:
            raise LimitError(
                f"watchdog time {ms} ms outside 0..2^32-1", device=self.device, command="watchdog"
            )
        self.send(Cmd.WATCHDOG, Watchdog(ms, WatchdogAction(action)))

    def heartbeat(self, ms: int) -> None:
        """Command 30: the node sends a heartbeat (9) every ``ms`` (0 = off, the default)."""
        if not 0 <= ms <= 0xFFFFFFFF:
            raise LimitError(
                f"heartbeat period {ms} ms outside 0..2^32-1", device=self.device, command="heartbeat_setup"
            )
        self.send(Cmd.HEARTBEAT_SETUP, ms)

    @property
    def last_heartbeat(self) -> float | None:
        """``time.monotonic()`` of the last heartbeat received from this node."""
        return self.bus.last_heartbeat(self._node)

    def wait_heartbeat(self, timeout: float = 1.0) -> float:
        """Block until the next heartbeat arrives; returns its monotonic time."""
        bus, node = self.bus, self._node
        cond = bus.heartbeat_condition(node)
        with cond:
            before = bus.last_heartbeat(node)
            if not cond.wait_for(lambda: bus.last_heartbeat(node) != before, timeout):
                raise GripperTimeout(
                    f"no heartbeat within {timeout:g} s", device=self.device, command="heartbeat"
                )
            at = bus.last_heartbeat(node)
            assert at is not None
            return at
