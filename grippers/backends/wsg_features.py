"""The WSG's optional features (grippers/device.py): objects the :class:`~grippers.backends.wsg.WsgDevice`
offers, each over the client in use (a reconnection swaps it in). Units: m and N in, mm and N on the wire.
"""

from __future__ import annotations

from collections.abc import Callable
from typing import TYPE_CHECKING, Any, Protocol

from grippers.drivers.errors import CommandFailed
from grippers.drivers.wsg.client import WsgClient
from grippers.drivers.wsg.commands import SystemInfo
from grippers.drivers.wsg.protocol import Status

from ..device import DeviceContext

if TYPE_CHECKING:
    from ..servo import ServoTarget

__all__ = [
    "SERVO_TOLERANCE",
    "WsgDeviceTag",
    "WsgReconnection",
    "WsgServo",
    "WsgSoftLimits",
    "WsgTemperature",
]


class Holder(Protocol):
    """What a feature asks of the :class:`~grippers.backends.wsg.WsgDevice` that offers it (declared here, so
    this module does not import the device's, which imports this one)."""

    @property
    def driver(self) -> WsgClient: ...

    @property
    def system_info(self) -> SystemInfo: ...

    @property
    def context(self) -> DeviceContext: ...

    def swap(self, client: WsgClient, system_info: SystemInfo) -> None: ...


class _Feature:
    """An optional feature over the device's client of the moment (a reconnection swaps the client)."""

    def __init__(self, device: Holder) -> None:
        self._device = device


class WsgSoftLimits(_Feature):
    def set(self, min_width: float | None, max_width: float | None) -> None:
        c = self._device.driver
        if min_width is None or max_width is None:
            c.clear_soft_limits()
        else:
            c.set_soft_limits(min_width * 1000, max_width * 1000)


class WsgTemperature(_Feature):
    def read(self) -> float:
        return self._device.driver.temperature()


class WsgDeviceTag(_Feature):
    def read(self) -> str:
        return self._device.driver.device_tag()

    def write(self, tag: str) -> None:
        self._device.driver.set_device_tag(tag)


# A running servo motion is not interrupted for a new target within this distance (m) of its own: STOP halts
# the fingers at once (manual §3.2.3), so re-targeting every control step would restart from rest each time
# and never reach speed. The new target is offered again when the motion ends (latest wins).
SERVO_TOLERANCE = 0.002


class WsgServo(_Feature):
    """Streamed targets as pre-positions sent without waiting (grippers/servo.py calls these)."""

    def __init__(self, device: Holder) -> None:
        super().__init__(device)
        self.reset()

    def reset(self) -> None:
        self._pending: Any = None
        self._aim: tuple[float, float] | None = None  # (width, speed) of the running servo motion
        self._force: float | None = None

    def begin(self) -> None:
        self.reset()

    def send(self, target: ServoTarget) -> bool | None:
        c = self._device.driver
        if target.force is not None and target.force != self._force:
            c.set_force_limit(target.force)  # 32h: preposition itself has no force argument
            self._force = target.force
        pending = self._pending
        running = pending is not None and not pending.done()
        if running and self._aim is not None:
            width, speed = self._aim
            if abs(target.width - width) <= SERVO_TOLERANCE and target.speed == speed:
                return None  # heading close by already; offered again once this motion has ended
        elif not running and self._aim == (target.width, target.speed):
            return False  # already there
        if not running and c.motion_outstanding():
            # A motion of another call (move(), grasp()) holds the motion slot: put the target off (offered
            # again shortly) instead of blocking this thread behind it, since stop() ends servoing by
            # waiting for this thread before its STOP goes out (issue 23 §1: the jaws travelled 15 mm more).
            return None
        if running:
            # WSG manual 4.0.x and 2.2.0 §3.2.2: a motion command while another runs is refused with
            # E_ALREADY_RUNNING ("Issue a STOP command, first"). STOP (22h, §3.2.3) ends the running one at
            # once; its final reply (E_CMD_ABORTED) comes before STOP's own, so the 21h slot is free after it.
            c.stop()
        try:
            self._pending = c.preposition(target.width * 1000, target.speed * 1000, wait=False)
        except CommandFailed as exc:
            if exc.status != Status.E_ALREADY_RUNNING:
                raise
            c.stop()  # a motion we did not start (another program, the web interface) was running
            self._pending = c.preposition(target.width * 1000, target.speed * 1000, wait=False)
        self._aim = (target.width, target.speed)
        return True

    def end(self) -> None:
        pending = self._pending
        if pending is not None and not pending.done():
            self._device.driver.stop()  # the next motion command would meet E_ALREADY_RUNNING otherwise
        self._pending = None


class WsgReconnection(_Feature):
    """Re-establishing a lost link (grippers/reconnect.py calls these)."""

    def __init__(self, device: Holder, connect: Callable[[], WsgClient]) -> None:
        super().__init__(device)
        self._connect = connect  # the client as it was opened: dials exactly what was opened

    def alive(self) -> bool:
        c = self._device.driver
        return c.connection_lost is None and not c.closed

    def identity(self) -> dict[str, str]:
        return _identity(self._device.system_info)

    def reconnect(self) -> None:
        old = self._device.driver
        if old.connection_lost is None and not old.closed:
            # UDP, CAN, or a serial line that is still open: the link never broke, the device went silent.
            # It answering again is the reconnection; the same client (and its bound port) carries on.
            new = old
        else:
            old.close()  # a serial port must be free before it is opened again
            new = self._reopen(old)
        try:
            found = new.system_info()  # the firmware version decides which commands exist
            self._device.context.check_same_device(_identity(found))  # never drive another gripper
        except BaseException:
            if new is not old:
                new.close()
            raise
        self._device.swap(new, found)

    def _reopen(self, old: WsgClient) -> WsgClient:
        """A client like ``old`` on the same URL (a serial port keeps the framing ``old`` used)."""
        common: dict[str, Any] = {
            "device": old.device,
            "timeout": old.timeout,
            "motion_timeout": old.motion_timeout,
        }
        t: Any = old.transport
        framing = getattr(t, "framing", None)
        if framing is not None:  # a serial line: keep the framing that was used
            return WsgClient.serial(t.port, **framing, **common)
        return self._connect()


def _identity(info: SystemInfo) -> dict[str, str]:
    """What tells one WSG from another: device type and serial of 50h (WSG manual 4.0.x §3.5.1)."""
    return {"device type": str(int(info.device_type)), "serial": str(info.serial)}
