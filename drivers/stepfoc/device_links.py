"""The two links under :class:`~grippers.drivers.stepfoc.device.StepfocDevice`: CAN and UART, in device units.

The framer/transport split of pymodbus: the device object (device.py) owns what a motion *means* (the poll
loop, the trackers, the supersede counter); a link only turns "status", "go", "halt" into its wire's requests
through the client underneath (:class:`~.can_client.StepfocNode`, :class:`~.uart_client.StepfocUart`).
Position 0 is fully open and 255 fully closed, speed is a byte, current is mA: no millimetre appears here.
"""

from __future__ import annotations

import threading
from collections.abc import Callable
from dataclasses import dataclass
from typing import TYPE_CHECKING, Any

from ..errors import ProtocolError
from .can_protocol import Detection, GripperStatus
from .motion import Reading, Verdict

if TYPE_CHECKING:
    import asyncio

    from .can_client import StepfocBus, StepfocNode
    from .uart_client import StepfocUart

__all__ = ["CanLink", "Link", "Status", "StatusCallback", "UartLink", "status_from_can"]


@dataclass(frozen=True, slots=True)
class Status:
    """What both links report, in device units."""

    position: int
    current_ma: int | None
    detection: Detection
    calibrated: bool
    activated: bool
    action: bool
    estop: bool
    faults: tuple[str, ...]

    def reading(self) -> Reading:
        """What the sans-IO trackers (motion.py) take."""
        return Reading(self.position, int(self.detection), self.calibrated, self.current_ma)


StatusCallback = Callable[["Status | None", "BaseException | None"], None]


def status_from_can(st: GripperStatus, cause: str | None) -> Status:
    """``cause``: the node's fault names (StepfocNode.fault: the 60 flags, else frame 26 for the error)."""
    names = [] if cause is None else cause.split(",")
    faults = tuple("fast_stop" if n == "estop" else "timeout" if n == "watchdog" else n for n in names)
    return Status(
        st.position,
        st.current_ma,
        Detection(st.detection),
        st.calibrated,
        st.activated,
        st.action,
        "estop" in names,
        faults,
    )


class Link:
    """The operations a device needs from a client, in device units."""

    driver: Any
    has_temperature = False

    def temperature(self) -> float:
        raise NotImplementedError

    def status(self) -> Status:
        raise NotImplementedError

    def start_status(self, done: StatusCallback) -> Callable[[], None] | None:
        """:meth:`status` without blocking: ``done`` is called from the client's reader; returns what gives
        the read up. None: this link reads only by blocking (the client times the read out itself)."""
        return None

    def go(self, position: int, speed: int, current_ma: int) -> None:
        raise NotImplementedError

    def halt(self) -> None:
        """Stop the motion where it is (no stop command exists: action bit cleared / deactivated)."""
        raise NotImplementedError

    def calibrate(self) -> None:
        """Start a calibration (after checking that no driver error would keep it from running)."""
        raise NotImplementedError

    def calibration_verdict(self, st: Status, now: float) -> Verdict:
        """RUNNING, ENDED or RETRY (ended without success: start it once more); CommandFailed if it failed."""
        raise NotImplementedError

    def estop(self) -> None:
        raise NotImplementedError

    def clear(self) -> None:
        raise NotImplementedError

    def identity(self) -> dict[str, Any]:
        """``serial``, ``firmware``, ``hardware`` (str or None) and ``extra`` (a dict)."""
        raise NotImplementedError

    def serial(self) -> str | None:
        """What tells this device from another on reconnection (None: the link cannot say)."""
        return None

    def servo(self, position: int, speed: int, current_ma: int, *, first: bool) -> bool:
        """Send one streamed target unless the gripper already heads there (``first``: always send).
        True if a frame went out."""
        raise NotImplementedError

    def alive(self) -> bool:
        raise NotImplementedError

    def reopened(self) -> Link:
        """After the link was lost: the link that reaches the device again (this one, or a fresh one the
        caller swaps in and whose old one it closes); raises while the device does not answer."""
        raise NotImplementedError

    def read_on(self, loop: asyncio.AbstractEventLoop) -> Callable[[], None] | None:
        """Let ``loop`` read the transport itself; returns what undoes it (None: the client keeps its
        reader)."""
        return None

    def abandon(self, thread_ident: int) -> None:
        self.driver.abandon(thread_ident)

    def resume(self, thread_ident: int) -> None:
        self.driver.resume(thread_ident)

    def close(self) -> None:
        raise NotImplementedError


class CanLink(Link):
    """One node on a CAN bus shared by every node opened on it in this process (:meth:`open`)."""

    # One StepfocBus per (interface, channel) in this process, shared by every node opened on it: a single
    # reader dispatches replies by node id (issue 3), and two readers on one SocketCAN socket would race.
    _buses: dict[tuple[str, str], tuple[StepfocBus, int]] = {}
    _buses_lock = threading.Lock()
    has_temperature = True

    def __init__(
        self,
        interface: str,
        channel: str,
        bitrate: int,
        node: int,
        current_limit: int,
        timeout: float,
        port: int | None = None,
    ):
        from .can_client import StepfocBus

        # udp_multicast's port= (python-can): a private port isolates a bus where groups do not (Linux)
        extra: dict[str, Any] = {} if port is None else {"port": port}
        self._key = (interface, channel if port is None else f"{channel}:{port}")
        with self._buses_lock:
            bus, count = self._buses.get(self._key, (None, 0))
            if bus is None:
                bus = StepfocBus(interface=interface, channel=channel, bitrate=bitrate, **extra)
            self._buses[self._key] = (bus, count + 1)
        self.node_id = node
        try:
            self.driver: StepfocNode = bus.node(node, current_limit_ma=current_limit, timeout=timeout)
        except BaseException:
            self._release_bus()
            raise

    @classmethod
    def shared_buses(cls) -> list[tuple[str, str]]:
        """The (interface, channel) keys of the buses open in this process (each closes with its last
        node)."""
        with cls._buses_lock:
            return list(cls._buses)

    def status(self) -> Status:
        st = self.driver.poll()
        return status_from_can(st, self.driver.fault(st))

    def start_status(self, done: StatusCallback) -> Callable[[], None] | None:
        def finished(st: GripperStatus | None, cause: str | None, error: BaseException | None) -> None:
            if st is None:
                done(None, error)
            else:
                done(status_from_can(st, cause), None)

        read = self.driver.start_status(finished)
        return None if read is None else read.cancel

    def go(self, position: int, speed: int, current_ma: int) -> None:
        self.driver.command(position, speed, current_ma, activate=True, action=True, estop=False)

    def halt(self) -> None:
        # The firmware has no stop command: a 61 with the action bit cleared halts the motion where it is
        # (Gripper_mode's "idle or disabled" branch), whatever its position byte says.
        last = self.driver.last_command
        position = last.position if last is not None else self.driver.poll().position
        speed = last.speed if last is not None else 0
        self.driver.command(position, speed, None, activate=True, action=False, estop=False)

    def temperature(self) -> float:
        return float(self.driver.temperature())

    def calibrate(self) -> None:
        # start_calibration polls first: an active error (frame 26 names it) would idle the 62 at once
        self._tracker = self.driver.start_calibration(command="home")

    def calibration_verdict(self, st: Status, now: float) -> Verdict:
        return self._tracker.update(st.reading(), now)

    def estop(self) -> None:
        self.driver.estop()

    def clear(self) -> None:
        self.driver.clear_error()

    def identity(self) -> dict[str, Any]:
        info = self.driver.device_info()
        return {
            "serial": str(info.serial),
            "firmware": str(info.software_version),
            "hardware": str(info.hardware_version),
            "extra": {"node": self.node_id, "batch_date": info.batch_date},
        }

    def serial(self) -> str | None:
        serial = self.identity().get("serial")
        return None if serial is None else str(serial)

    def servo(self, position: int, speed: int, current_ma: int, *, first: bool) -> bool:
        node = self.driver
        cmd = node.make_command(position, speed, current_ma)
        if cmd == node.last_command and not first:
            return False  # the gripper already heads there; the firmware would take it as "same"
        # One 61 per target; returns with its 60 reply. A first frame equal to the last 61 (the "same
        # command" latch, docs/protocols.md §2) is made to differ by the node itself (send_command).
        node.send_command(cmd)
        return True

    def alive(self) -> bool:
        bus, _ = self._buses.get(self._key, (None, 0))
        return bus is not None and bool(bus.alive)

    def reopened(self) -> Link:
        # A bus whose interface went down or away is opened afresh (drivers/canlink.py); one that never
        # failed stays: the node answering again is the reconnection.
        self.driver.bus.reopen()
        self.status()
        return self

    def read_on(self, loop: asyncio.AbstractEventLoop) -> Callable[[], None] | None:
        bus = self.driver.bus  # shared by the nodes on it; the same object after a reopen
        if not bus.attach_loop(loop):
            return None
        return lambda: bus.detach_loop(loop)

    def _release_bus(self) -> None:
        with self._buses_lock:
            bus, count = self._buses[self._key]
            if count <= 1:
                del self._buses[self._key]
                bus.close()
            else:
                self._buses[self._key] = (bus, count - 1)

    def close(self) -> None:
        self._release_bus()


class UartLink(Link):
    """The MSG's UART text interface (one gripper per port)."""

    def __init__(self, port: str, baudrate: int, current_limit: int, timeout: float) -> None:
        from .uart_client import StepfocUart

        self.port = port
        self.driver: StepfocUart = StepfocUart(
            port, baudrate=baudrate, timeout=timeout, current_limit_ma=current_limit
        )
        self._go_lock = threading.Lock()
        self._servo_last: tuple[int, int, int] | None = None  # the last streamed target sent

    def status(self) -> Status:
        info = self.driver.gripinfo()
        position = self.driver.position()
        try:
            detection = Detection(int(info.detection))
        except ValueError:  # the parser keeps a value outside 0..3 as the int printed
            raise ProtocolError(
                f"object detection status {info.detection!r} is not 0..3",
                device=self.port,
                command="Gripinfo",
            ) from None
        return Status(
            position,
            None,  # the UART reports setpoints, not the measured current
            detection,
            bool(info.calibrated),
            bool(info.activated),
            bool(info.action),
            bool(info.estop),
            ("fast_stop",) if info.estop else (),
        )

    def halt(self) -> None:
        with self._go_lock:
            self.driver.activate(0)  # the UART has no action bit: deactivating is its only way to stop

    def go(self, position: int, speed: int, current_ma: int) -> None:
        # Three text commands make one motion: a stop() from another thread must not land between them and
        # be undone by the final Grippos, so the sequence holds a lock.
        d = self.driver
        with self._go_lock:
            d.velocity(speed)
            d.current(current_ma)
            d.position(position)  # a set also activates and starts the motion (docs/protocols.md §2)

    def calibrate(self) -> None:
        self.driver.start_calibration(command="home")  # #Error first: an error would idle it unseen

    def calibration_verdict(self, st: Status, now: float) -> Verdict:
        return self.driver.calibration_verdict(command="home")

    def estop(self) -> None:
        self.driver.estop(1)

    def clear(self) -> None:
        # Gripstop 0 only clears the estop bit; the error itself stays until #Clear (STEPFOC firmware, as
        # the CAN side's command 1), and Gripinfo shows the bit, not the error.
        self.driver.estop(0)
        self.driver.clear_error()

    def identity(self) -> dict[str, Any]:
        info = self.driver.info()
        return {
            "serial": None,
            "firmware": str(info.software_version),
            "hardware": str(info.hardware_version),
            "extra": {"node": info.can_id, "batch_date": info.batch_date, "port": self.port},
        }

    def servo(self, position: int, speed: int, current_ma: int, *, first: bool) -> bool:
        if (position, speed, current_ma) == self._servo_last and not first:
            return False
        self.go(position, speed, current_ma)  # Gripvel, Gripcur, Grippos (docs/protocols.md §2)
        self._servo_last = (position, speed, current_ma)
        return True

    def alive(self) -> bool:
        return not self.driver.closed

    def reopened(self) -> Link:
        d = self.driver
        baudrate = d.baudrate
        d.close()  # the port is opened exclusively (drivers/serial_ports.py): free it before opening it again
        fresh = UartLink(self.port, baudrate, d.current_limit_ma, d.timeout)
        try:
            fresh.status()
        except BaseException:
            fresh.close()
            raise
        return fresh

    def close(self) -> None:
        self.driver.close()
