"""The MSG's optional features (grippers/device.py): objects the :class:`~grippers.backends.stepfoc.MsgDevice`
offers, each over the driver's device object (a reconnection swaps its link). Units: m, m/s and N in, the
profile's position, speed and current maps on the wire (the device's ``position_byte``, ``speed_byte``,
``current_ma``).
"""

from __future__ import annotations

from typing import TYPE_CHECKING, Protocol

from grippers.drivers.stepfoc.device import StepfocDevice

from ..device import DeviceContext

if TYPE_CHECKING:
    from ..servo import ServoTarget

__all__ = ["MsgHolder", "MsgReconnection", "MsgServo", "MsgTemperature"]


class MsgHolder(Protocol):
    """What a feature asks of the :class:`~grippers.backends.stepfoc.MsgDevice` that offers it (declared
    here, so this module does not import the device's, which imports this one)."""

    msg: StepfocDevice
    mode: str  # what the last motion was, to name what the detection bits mean
    held: bool  # a grasp found its part

    @property
    def context(self) -> DeviceContext: ...

    def position_byte(self, width: float) -> int: ...

    def speed_byte(self, speed: float) -> int: ...

    def current_ma(self, force: float | None) -> int: ...


class MsgTemperature:
    """``temperature()``: the driver's own sensor, offered where the link has one (``has_temperature``)."""

    def __init__(self, msg: StepfocDevice) -> None:
        self._msg = msg

    def read(self) -> float:
        return float(self._msg.link.temperature())


class MsgServo:
    """Streamed targets: one motion frame (CAN 61, UART Gripvel/Gripcur/Grippos) per new target."""

    def __init__(self, device: MsgHolder) -> None:
        self._device = device

    def begin(self) -> None:
        self._device.msg.servo_begin()

    def send(self, target: ServoTarget) -> bool:
        d = self._device
        if not d.msg.servo(
            d.position_byte(target.width), d.speed_byte(target.speed), d.current_ma(target.force)
        ):
            return False
        d.mode, d.held = "move", False
        return True

    def end(self) -> None:
        return None


class MsgReconnection:
    """``reconnect=true``: the same node again on a fresh link, refused when another MSG answers there."""

    def __init__(self, device: MsgHolder) -> None:
        self._device = device

    def alive(self) -> bool:
        return self._device.msg.alive()

    def identity(self) -> dict[str, str]:
        serial = self._device.msg.link.serial()  # the UART protocol reports none: nothing to compare
        return {} if serial is None else {"serial": serial}

    def reconnect(self) -> None:
        d = self._device
        d.msg.reconnect()
        d.context.check_same_device(self.identity())  # another MSG put on this node is refused
        d.mode, d.held = "idle", False  # a power-cycled gripper lost anything it held
