"""The MSG-on-STEPFOC backend: raw position/speed bytes and milliamps behind the SI :class:`Gripper`.

The driver knows no millimetres: position 0 is fully open and 255 fully closed between the calibrated end
stops, speed is a byte, and force is only a current limit. The profile's maps turn widths, speeds and
newtons into those numbers here, once. Two links (CAN and UART) offer the same few operations through
:class:`_Link`, so the grasp logic is written once for both.
"""

from __future__ import annotations

import threading
import time
import uuid
from collections.abc import Callable
from dataclasses import dataclass
from typing import TYPE_CHECKING, Any

from grippers.drivers.stepfoc.can_protocol import Detection, GripperStatus
from grippers.drivers.stepfoc.motion import CalibrationTracker, MotionTracker, Reading, Verdict
from grippers.drivers.stepfoc.speed import speed_byte_for, variant

from ..errors import (
    CommandFailed,
    ConnectionLost,
    GripperTimeout,
    MotionBlocked,
    NotReferenced,
    ProtocolError,
    URLError,
)
from ..gripper import (
    Capability,
    DeviceInfo,
    GraspResult,
    GraspState,
    Gripper,
    GripperState,
    MotionResult,
    StartedRead,
    StateCallback,
)
from ..profiles import ProfileBase, load_profile
from ..settings import Settings
from ..urls import ConnectionURL
from .motion_epochs import MotionEpochs
from .stepfoc_profile import MsgProfile

if TYPE_CHECKING:
    import asyncio

DEFAULT_PROFILE = "msg-150"  # the MSG cannot report its rail length: profile= chooses another
POLL_PERIOD = 0.01  # s between status polls while waiting for a motion; a CAN round trip is ~0.2 ms
# A motion that reports "moving" while the jaws stand still has ended without its target: the driver was idled
# (clear error, idle, watchdog from elsewhere; the 60 frame cannot show the driver mode) or it pushes below
# the firmware's contact current. Stalled for this long (and at least STALL_BYTES_TIME position steps at the
# commanded speed), the wait ends with "aborted".
STALL_MIN_S = 0.5
STALL_BYTES_TIME = 4
# state().moving: the bits alone would say "moving" for ever once the driver was idled (clear error, idle,
# watchdog) with the stored 61's activate and action bits still set and detection 0 (the firmware's "idle or
# disabled" branch). While no motion of ours waits, the jaws decide: standing still this long is not moving.
STILL_S = 0.3


class _Retry(Exception):
    """The calibration ended without success; the caller may start it once more."""

    def __init__(self, status: _Status) -> None:
        super().__init__("calibration ended without success")
        self.status = status


@dataclass(frozen=True, slots=True)
class _Status:
    """What both links report, in device units."""

    position: int
    current_ma: int | None
    detection: Detection
    calibrated: bool
    activated: bool
    action: bool
    estop: bool
    faults: tuple[str, ...]


_StatusCallback = Callable[["_Status | None", "BaseException | None"], None]


class _Link:
    """The operations the gripper needs from a driver, in device units."""

    driver: Any
    has_temperature = False

    def temperature(self) -> float:
        raise NotImplementedError

    def status(self) -> _Status:
        raise NotImplementedError

    def start_status(self, done: _StatusCallback) -> StartedRead | None:
        """:meth:`status` without blocking: ``done`` is called from the driver's reader. None: this link
        reads only by blocking."""
        return None

    def go(self, position: int, speed: int, current_ma: int, *, action: bool = True) -> None:
        raise NotImplementedError

    def halt(self) -> None:
        """Stop the motion where it is (no stop command exists: action bit cleared / deactivated)."""
        raise NotImplementedError

    def calibrate(self) -> None:
        """Start a calibration (after checking that no driver error would keep it from running)."""
        raise NotImplementedError

    def calibration_verdict(self, st: _Status, now: float) -> Verdict:
        """RUNNING, ENDED or RETRY (ended without success: send 62 once more); CommandFailed if it failed."""
        raise NotImplementedError

    def estop(self) -> None:
        raise NotImplementedError

    def clear(self) -> None:
        raise NotImplementedError

    def identity(self) -> dict[str, Any]:
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

    def reopened(self) -> _Link:
        """After the link was lost: the link that reaches the device again (this one, or a fresh one the
        caller swaps in and whose old one it closes); raises while the device does not answer."""
        raise NotImplementedError

    def read_on(self, loop: asyncio.AbstractEventLoop) -> Callable[[], None] | None:
        """:meth:`Gripper._read_on` for this link (default: the driver keeps its reader)."""
        return None

    def close(self) -> None:
        raise NotImplementedError


def _from_can(st: GripperStatus, cause: str | None) -> _Status:
    """``cause``: the node's fault names (StepfocNode.fault: the 60 flags, else frame 26 for the error)."""
    names = [] if cause is None else cause.split(",")
    estop = "estop" in names
    faults = tuple("fast_stop" if n == "estop" else "timeout" if n == "watchdog" else n for n in names)
    return _Status(
        st.position,
        st.current_ma,
        Detection(st.detection),
        st.calibrated,
        st.activated,
        st.action,
        estop,
        faults,
    )


class _CanLink(_Link):
    # One StepfocBus per (interface, channel) in this process, shared by every node opened on it: a single
    # reader dispatches replies by node id (issue 3), and two readers on one SocketCAN socket would race.
    _buses: dict[tuple[str, str], tuple[Any, int]] = {}
    _buses_lock = threading.Lock()

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
        from grippers.drivers.stepfoc.can_client import StepfocBus

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
            self.driver = bus.node(node, current_limit_ma=current_limit, timeout=timeout)
        except BaseException:
            self._release_bus()
            raise

    def status(self) -> _Status:
        st = self.driver.poll()
        return _from_can(st, self.driver.fault(st))

    def start_status(self, done: _StatusCallback) -> StartedRead | None:
        def finished(st: GripperStatus | None, cause: str | None, error: BaseException | None) -> None:
            if st is None:
                done(None, error)
            else:
                done(_from_can(st, cause), None)

        read = self.driver.start_status(finished)
        # The bus times each request out itself (its reader's clock), so no caller timer: the poll and the
        # error-cause read end as the threaded call's do, frame 26 unanswered included ("error").
        return None if read is None else StartedRead(read.cancel, None)

    def go(self, position: int, speed: int, current_ma: int, *, action: bool = True) -> None:
        self.driver.command(position, speed, current_ma, activate=True, action=action, estop=False)

    def halt(self) -> None:
        # The firmware has no stop command: a 61 with the action bit cleared halts the motion where it is
        # (Gripper_mode's "idle or disabled" branch), whatever its position byte says.
        last = self.driver.last_command
        position = last.position if last is not None else self.driver.poll().position
        speed = last.speed if last is not None else 0
        self.driver.command(position, speed, None, activate=True, action=False, estop=False)

    has_temperature = True

    def temperature(self) -> float:
        return float(self.driver.temperature())

    def calibrate(self) -> None:
        # start_calibration polls first: an active error (frame 26 names it) would idle the 62 at once
        self._tracker = self.driver.start_calibration(command="home")

    def calibration_verdict(self, st: _Status, now: float) -> Verdict:
        tracker: CalibrationTracker = self._tracker
        return tracker.update(Reading(st.position, int(st.detection), st.calibrated, st.current_ma), now)

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

    def reopened(self) -> _Link:
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


class _UartLink(_Link):
    def __init__(self, port: str, baudrate: int, current_limit: int, timeout: float) -> None:
        from grippers.drivers.stepfoc.uart_client import StepfocUart

        self.port = port
        self.driver = StepfocUart(port, baudrate=baudrate, timeout=timeout, current_limit_ma=current_limit)
        self._go_lock = threading.Lock()
        self._servo_last: tuple[int, int, int] | None = None  # the last streamed target sent

    def status(self) -> _Status:
        info = self.driver.gripinfo()
        position = self.driver.position()
        faults = ("fast_stop",) if info.estop else ()
        try:
            detection = Detection(int(info.detection))
        except ValueError:  # the parser keeps a value outside 0..3 as the int printed
            raise ProtocolError(
                f"object detection status {info.detection!r} is not 0..3",
                device=self.port,
                command="Gripinfo",
            ) from None
        return _Status(
            position,
            None,  # the UART reports setpoints, not the measured current
            detection,
            bool(info.calibrated),
            bool(info.activated),
            bool(info.action),
            bool(info.estop),
            faults,
        )

    def halt(self) -> None:
        with self._go_lock:
            self.driver.activate(0)  # the UART has no action bit: deactivating is its only way to stop

    def go(self, position: int, speed: int, current_ma: int, *, action: bool = True) -> None:
        # Three text commands make one motion: a stop() from another thread must not land between them and
        # be undone by the final Grippos, so the sequence holds a lock.
        d = self.driver
        with self._go_lock:
            d.velocity(speed)
            d.current(current_ma)
            if action:
                d.position(position)  # a set also activates and starts the motion (docs/protocols.md §2)
            else:
                d.activate(0)  # the UART has no action bit: deactivating is its only way to stop

    def calibrate(self) -> None:
        self.driver.start_calibration(command="home")  # #Error first: an error would idle it unseen

    def calibration_verdict(self, st: _Status, now: float) -> Verdict:
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

    def reopened(self) -> _Link:
        d = self.driver
        fresh = _UartLink(self.port, d._ser.baudrate, d.current_limit_ma, d.timeout)
        try:
            fresh.status()
        except BaseException:
            fresh.close()
            raise
        return fresh

    def close(self) -> None:
        self.driver.close()


class MsgGripper(Gripper):
    capabilities = frozenset({Capability.CURRENT_CONTROL, Capability.CALIBRATION})

    def __init__(
        self, link: _Link, profile: MsgProfile, url: str, *, timeout: float, profile_assumed: bool = False
    ) -> None:
        super().__init__(profile, url, timeout=timeout)
        self._link = link
        self._profile_assumed = profile_assumed
        # Motion bookkeeping at the device level: every motion this backend starts (and every stop) takes a
        # new number; a wait whose number is no longer the current one ends with the recorded cause.
        self._epochs = MotionEpochs()
        self._send_lock = threading.RLock()  # a motion's number and its frames go out together
        if link.has_temperature:
            self.capabilities = self.capabilities | {Capability.TEMPERATURE}
        self._maps = profile.maps
        # Force is a current limit here: a force beyond what the (safety) current limit gives, or below the
        # stable minimum current, would be silently changed by _current_ma, so the limits say so up front.
        npa = profile.maps.newton_per_amp
        self.limits = self.limits.model_copy(
            update={
                "max_force": min(self.limits.max_force, profile.effective_max_current_ma / 1000 * npa),
                "min_force": max(self.limits.min_force, profile.maps.min_current_ma / 1000 * npa),
            }
        )
        self._mode = "idle"  # what the last motion was, to name what the detection bits mean
        self._held = False  # a grasp found its part; detection 3 afterwards means the part was lost
        # The calibrated bit as last read (None: not read since open or a reconnection). The firmware ignores
        # a motion frame until it is calibrated (Gripper_mode, docs/protocols.md §2), so a motion
        # asks first, unless a read already said so: the bit is lost only at power-off (a reconnection).
        self._calibrated: bool | None = None
        self._waits = 0  # motion waits in progress (state().moving trusts the bits while one runs)
        self._waits_lock = threading.Lock()
        self._seen_position: int | None = None  # the last position read and when it last changed
        self._seen_change = 0.0

    @property
    def driver(self) -> Any:
        return self._link.driver

    # -- unit maps (profile maps; docs/protocols.md §2 for the byte meanings) --------------------------------

    def _position_byte(self, width: float) -> int:
        m = self._maps
        span = m.open_width_mm - m.closed_width_mm
        return max(0, min(255, round((m.open_width_mm - width * 1000) / span * 255)))

    def _width_of(self, position: int) -> float:
        m = self._maps
        return (m.open_width_mm - position / 255 * (m.open_width_mm - m.closed_width_mm)) / 1000

    def _speed_byte(self, speed: float) -> int:
        # the one speed model (drivers/stepfoc/speed.py): the fastest byte not faster than asked
        m = self._maps
        return speed_byte_for(speed * 1000, m.ticks_per_mm, variant(m.driver))

    def _current_ma(self, force: float | None) -> int:
        m = self._maps
        if force is None:
            return m.default_current_ma
        assert isinstance(self.profile, MsgProfile)
        limit = self.profile.effective_max_current_ma
        return max(m.min_current_ma, min(limit, round(force / m.newton_per_amp * 1000)))

    # -- motion ----------------------------------------------------------------------------------------

    def _begin(self, cause: str) -> int:
        """A new motion (or stop) from this backend: the waits of older ones end with ``cause``."""
        return self._epochs.begin(cause)

    def _check_current(self, motion: int, command: str) -> None:
        self._epochs.check(motion, command=command, device=self.name)

    def _check_device(self, st: _Status, command: str) -> None:
        if st.estop:
            from ..gripper import FastStopActive

            self._fast_stopped = True
            raise FastStopActive(
                f"{command} aborted: e-stop active on the gripper", device=self.name, command=command
            )
        if st.faults:  # a watchdog or temperature error idles the driver; waiting would only time out
            raise CommandFailed(
                f"{command} aborted by a device error: {', '.join(st.faults)}",
                status_name=",".join(st.faults),
                device=self.name,
                command=command,
            )

    def _wait(
        self, command: str, motion: int, timeout: float, done: Any, *, stall_s: float | None = None
    ) -> _Status:
        """Poll until ``done(status)``. Ends early, never reporting success, when this backend started a
        newer motion or a stop, the device shows an e-stop or an error, the action or activate bit was
        cleared by someone else, or (``stall_s``) the jaws stood still for that long while "moving"."""
        with self._waits_lock:
            self._waits += 1
        try:
            return self._poll_until(command, motion, timeout, done, stall_s)
        finally:
            with self._waits_lock:
                self._waits -= 1

    def _poll_until(
        self, command: str, motion: int, timeout: float, done: Any, stall_s: float | None
    ) -> _Status:
        """``done(status, now)`` returns a :class:`Verdict` (or a bool): ARRIVED / OBJECT / ENDED end the
        wait, STALLED ends it as aborted, RETRY is the caller's (raised as _Retry)."""
        deadline = time.monotonic() + timeout
        while True:
            if self._closed:  # close() from another thread: do not poll a closed link until the deadline
                raise ConnectionLost(
                    "the gripper was closed during the motion", device=self.name, command=command
                )
            self._check_current(motion, command)
            st = self._link.status()
            self._calibrated = bool(st.calibrated)
            self._check_current(motion, command)  # a stop sent while this poll ran
            self._check_device(st, command)
            now = time.monotonic()
            if stall_s is not None and not (st.activated and st.action):
                raise CommandFailed(
                    f"{command} aborted: the gripper's action bit was cleared (a stop from another "
                    f"program?) at {self._width_of(st.position) * 1000:.1f} mm",
                    status_name="aborted",
                    device=self.name,
                    command=command,
                )
            verdict = done(st, now)
            if verdict in (Verdict.ARRIVED, Verdict.OBJECT, Verdict.ENDED):
                return st
            if verdict is Verdict.RETRY:
                raise _Retry(st)
            if verdict is Verdict.STALLED:
                if not st.calibrated and command != "home":  # powered off and on behind our back
                    raise NotReferenced(device=self.name, command=command)
                raise CommandFailed(
                    f"{command} aborted: the jaws stopped at {self._width_of(st.position) * 1000:.1f} mm "
                    "without reaching the target (the driver was idled or the motion stalled)",
                    status_name="aborted",
                    device=self.name,
                    command=command,
                )
            if now >= deadline:
                raise GripperTimeout(f"not done after {timeout:g} s", device=self.name, command=command)
            time.sleep(POLL_PERIOD)

    def _stall_s(self, speed: float) -> float:
        m = self._maps
        per_byte = (m.open_width_mm - m.closed_width_mm) / 1000 / 255 / max(speed, 1e-6)
        return max(STALL_MIN_S, STALL_BYTES_TIME * per_byte)

    def _go_and_wait(
        self, command: str, position: int, speed: float, current_ma: int, timeout: float
    ) -> _Status:
        with self._send_lock:  # a stop() cannot land between the number and the frames and be undone
            motion = self._begin(f"superseded by a newer motion before it ended ({command})")
            self._link.go(position, self._speed_byte(speed), current_ma)
        # The immediate reply to a new command still carries the previous detection value (docs/protocols.md
        # §2), so fresh polls decide, read by the sans-IO MotionTracker: 3 only at the target (the latch can
        # say 3 early), 1/2 only once the jaws moved or it lasted (the start-up current can say it early), and
        # a slow motion's late contact flag is waited for while the current shows the jaws pushing.
        stall = self._stall_s(speed)
        tracker = MotionTracker(None, position, time.monotonic(), stall_s=stall, limit_ma=current_ma)

        def done(st: _Status, now: float) -> Verdict:
            return tracker.update(Reading(st.position, int(st.detection), st.calibrated, st.current_ma), now)

        return self._wait(command, motion, timeout, done, stall_s=stall)

    def _home(self, timeout: float) -> None:
        with self._send_lock:
            motion = self._begin("superseded by a newer motion before it ended (home)")
            self._mode, self._held = "home", False
            self._link.calibrate()
        # Polls only (empty 61 / UART gets): a 5-byte 61 would abort the calibration (docs/protocols.md §2).
        # A calibration that ended without success (the firmware's 150,000-tick time-out, reached by the
        # ticks an aborted calibration left behind, or one that never ran) is started once more: the time-out
        # resets the calibration's step state, so the second one runs from the start.
        deadline = time.monotonic() + timeout
        for attempt in range(2):
            try:
                self._wait(
                    "home", motion, max(0.1, deadline - time.monotonic()), self._link.calibration_verdict
                )
                break
            except _Retry as retry:
                if attempt:
                    raise CommandFailed(
                        "calibration did not complete twice (the jaws rest at "
                        f"{self._width_of(retry.status.position) * 1000:.1f} mm, calibrated "
                        f"{int(retry.status.calibrated)})",
                        status_name="failed",
                        device=self.name,
                        command="home",
                    ) from None
                with self._send_lock:
                    self._check_current(motion, "home")
                    self._link.calibrate()
        self._mode = "idle"

    def _motion_timeout(self, distance: float, speed: float) -> float:
        # Calibration drives both ways at low current and pauses, and may run twice (a time-out of up to
        # 30 s of control ticks, then a full run): give it room, bounded.
        return max(super()._motion_timeout(distance, speed), 65.0)

    def _referenced(self, command: str, st: _Status | None = None) -> None:
        """Refuse a motion of an uncalibrated gripper before anything is sent: the firmware would ignore it
        (the jaws stay put), and the wait would end as a stall: "move aborted ... the motion stalled".

        The STEPFOC firmware moves only when ``action_status == 1 && calibrated && activated``
        (PCrnjak/STEPFOC-stepper-controller, ``src/motor_control.cpp`` ``Gripper_mode``, line 2240 at
        6e71832); the simulator follows it (drivers/stepfoc/sim/model.py ``_apply_motion``)."""
        if self._calibrated is not True or st is not None:
            st = st or self._link.status()
            self._calibrated = bool(st.calibrated)
        if not self._calibrated:
            raise NotReferenced(device=self.name, command=command)

    def _blocked(self, command: str, st: _Status, target: float) -> None:
        """A move or release that ended on an object short of its target is :class:`MotionBlocked` (it
        returned success with state HOLDING, issue 31 §1). The firmware keeps pushing with the motion's
        current until the next command; the error says where the jaws stand."""
        short = abs(self._width_of(st.position) - target) > MotionBlocked.MARGIN
        if short and st.detection in (Detection.CLOSING_OBJECT, Detection.OPENING_OBJECT):
            raise MotionBlocked(
                width=self._width_of(st.position), target=target, device=self.name, command=command
            )

    def _move(self, width: float, speed: float, timeout: float) -> MotionResult:
        self._referenced("move")
        self._mode, self._held = "move", False
        st = self._go_and_wait(
            "move", self._position_byte(width), speed, self._maps.default_current_ma, timeout
        )
        self._blocked("move", st, width)
        return MotionResult(self._width_of(st.position), self._grasp_state(st))

    def _grasp(self, width: float, speed: float, force: float, timeout: float) -> GraspResult:
        m = self._maps
        travel = m.grasp_travel_mm / 1000
        target = width + travel if m.inside_grip else width - travel
        target = min(max(target, self.limits.min_width), self.limits.max_width)
        # Jaws already past the part (after a calibration they rest closed): open to the far side first,
        # or the grasp would start where no part can be met.
        before = self._link.status()
        self._referenced("grasp", before)
        start = self._width_of(before.position)
        past = start > width + travel / 2 if m.inside_grip else start < width - travel / 2
        if past:
            approach = width - travel if m.inside_grip else width + travel
            approach = min(max(approach, self.limits.min_width), self.limits.max_width)
            self._mode, self._held = "release", False
            self._go_and_wait("grasp", self._position_byte(approach), speed, m.default_current_ma, timeout)
        self._mode, self._held = "grasp", False
        current = self._current_ma(force)
        st = self._go_and_wait("grasp", self._position_byte(target), speed, current, timeout)
        expected = Detection.OPENING_OBJECT if m.inside_grip else Detection.CLOSING_OBJECT
        held = st.detection == expected
        self._held = held
        est_force = current / 1000 * m.newton_per_amp
        return GraspResult(
            held,
            self._width_of(st.position),
            est_force if held else None,
            GraspState.HOLDING if held else GraspState.NO_PART,
            reason=None
            if held
            else f"reached {self._width_of(st.position) * 1000:.1f} mm without meeting a part",
        )

    def _grips_from_inside(self) -> bool:
        return self._maps.inside_grip

    def _default_release_width(self) -> float:
        # A part gripped from inside is let go by closing: "fully open" would push into it.
        return self.limits.min_width if self._maps.inside_grip else self.limits.max_width

    def _release(self, width: float, speed: float, timeout: float) -> MotionResult:
        self._referenced("release")
        self._mode, self._held = "release", False
        st = self._go_and_wait(
            "release", self._position_byte(width), speed, self._maps.default_current_ma, timeout
        )
        self._blocked("release", st, width)
        self._mode = "idle"
        return MotionResult(self._width_of(st.position), GraspState.IDLE)

    def _stop(self) -> None:
        # Safe from another thread and from a KeyboardInterrupt handler: the waiting motion learns of the
        # stop from the motion number (no lock held while sending), and the link serialises its frames.
        with self._send_lock:
            self._begin("aborted by stop()")
            self._link.halt()
        self._mode = "idle"

    def _fast_stop(self) -> None:
        self._begin("aborted by fast_stop()")  # no lock: an e-stop never waits for anything
        self._link.estop()

    def _acknowledge(self) -> None:
        self._link.clear()

    # -- state -----------------------------------------------------------------------------------------

    def _grasp_state(self, st: _Status) -> GraspState:
        if st.estop or st.faults:
            return GraspState.ERROR
        if st.detection == Detection.MOVING and st.activated and st.action:
            return {"grasp": GraspState.GRASPING, "release": GraspState.RELEASING}.get(
                self._mode, GraspState.POSITIONING
            )
        if st.detection in (Detection.CLOSING_OBJECT, Detection.OPENING_OBJECT):
            return GraspState.HOLDING
        if self._mode == "grasp" and st.detection == Detection.AT_POSITION:
            return GraspState.PART_LOST if self._held else GraspState.NO_PART
        return GraspState.IDLE

    def _state(self) -> GripperState:
        return self._state_of(self._link.status())

    def _read_on(self, loop: asyncio.AbstractEventLoop) -> Callable[[], None] | None:
        return self._link.read_on(loop)  # CAN only: the UART client reads on the calling thread

    def _start_state(self, done: StateCallback) -> StartedRead | None:
        # CAN only: the UART client reads its replies on the calling thread (a worker reads it instead)
        def finished(st: _Status | None, error: BaseException | None) -> None:
            if st is None:
                done(None, error)
                return
            try:
                state = self._state_of(st)
            except Exception as exc:  # noqa: BLE001 - handed to the caller: done is called once, always
                done(None, exc)
                return
            done(state, None)

        return self._link.start_status(finished)

    def _state_of(self, st: _Status) -> GripperState:
        """The state a status read says, whichever face read it."""
        self._calibrated = bool(st.calibrated)
        return GripperState(
            width=self._width_of(st.position),
            speed=None,
            force=None,
            current=None if st.current_ma is None else abs(st.current_ma) / 1000,
            grasp=self._grasp_state(st),
            moving=self._moving(st),
            referenced=st.calibrated,
            faults=st.faults,
            timestamp=time.time(),
        )

    def _moving(self, st: _Status) -> bool:
        now = time.monotonic()
        if st.position != self._seen_position:
            self._seen_position, self._seen_change = st.position, now
        if not (st.detection == Detection.MOVING and st.activated and st.action and st.calibrated):
            return False
        return self._waits > 0 or now - self._seen_change < STILL_S

    def _info(self) -> DeviceInfo:
        ident = self._link.identity()
        return DeviceInfo(
            family="stepfoc",
            vendor=self.profile.vendor,
            model=self.profile.model,
            serial=ident["serial"],
            firmware=ident["firmware"],
            hardware=ident["hardware"],
            limits=self.limits,
            url=self.url,
            profile=self.profile.name,
            extra=self._extra(ident["extra"]),
        )

    def _extra(self, extra: dict[str, Any]) -> dict[str, Any]:
        if not self._profile_assumed:
            return extra
        warning = f"model {self.profile.name} assumed (the MSG cannot report its rail length); pass a profile"
        return {**extra, "warnings": [*extra.get("warnings", []), warning]}

    def _temperature(self) -> float:
        return self._link.temperature()

    def _close(self) -> None:
        self._link.close()

    # -- streamed targets and reconnection (hooks of grippers/servo.py and grippers/reconnect.py) -------

    def _servo_begin(self) -> None:
        self._servo_first = True

    def _servo(self, target: Any) -> bool:
        position, speed = self._position_byte(target.width), self._speed_byte(target.speed)
        current = self._maps.default_current_ma if target.force is None else self._current_ma(target.force)
        if not self._link.servo(position, speed, current, first=self._servo_first):
            return False
        self._servo_first = False
        self._mode, self._held = "move", False
        return True

    def _abandon(self, thread_ident: int) -> None:
        self._link.driver.abandon(thread_ident)

    def _resume(self, thread_ident: int) -> None:
        self._link.driver.resume(thread_ident)

    def _link_alive(self) -> bool:
        return self._link.alive()

    def _identity(self) -> dict[str, str]:
        serial = self._link.serial()  # the UART protocol reports none: nothing to compare
        return {} if serial is None else {"serial": serial}

    def _reconnect(self) -> None:
        link = self._link
        fresh = link.reopened()
        if fresh is not link:
            self._link = fresh
            link.close()
        self._check_same_device(self._identity())  # another MSG put on this node is refused
        # A gripper that was power-cycled has lost its calibration (docs/protocols.md §2) and anything
        # it held.
        self._mode, self._held = "idle", False
        self._calibrated = None


UART_BAUD = 256000  # docs/protocols.md §2: the probe's speed on a bare serial port
PROBE_NODES = 16  # 4-bit node id (MSG manual, "Bits 10 - 7 of CAN ID")


class StepfocBackend:
    family = "stepfoc"
    profile_model = MsgProfile
    # What a bare transport's URL would be for an MSG (the "did you mean" of a mistyped target), ranked.
    bare_forms = {"serial": (20, "stepfoc+serial://{rest}"), "can": (10, "stepfoc+can://{rest}?node=0")}

    @property
    def cli_sim(self) -> Any:
        """``grippers sim``'s options and server start for this family (grippers/cli/sim.py asks for it)."""
        from . import stepfoc_cli

        return stepfoc_cli

    @property
    def device_settings(self) -> Any:
        """``grippers settings`` and ``selftest``: what this family stores besides its motion."""
        from .stepfoc_settings import StepfocDeviceSettings

        return StepfocDeviceSettings()

    def selftest_checks(self, gripper: Any, add: Callable[..., None]) -> None:
        """``grippers selftest``'s lines of this family (``add(name, measured, expected, verdict, note)``)."""
        from .stepfoc_settings import selftest_checks

        selftest_checks(gripper, add)

    def dissector(self) -> Any:
        """``grippers monitor``: STEPFOC CAN frames (its captures are candump logs)."""
        from grippers.drivers.stepfoc.dissect import StepfocCanDissector

        from . import Dissector

        return Dissector(StepfocCanDissector.protocol, can=lambda _o: StepfocCanDissector())

    def probe_candidates(self, transport: str, where: ConnectionURL, options: dict[str, Any]) -> list[Any]:
        """``grippers probe`` on a bare transport: the UART on a serial port, nodes 0-15 on a CAN bus."""
        from . import ProbeCandidate, bus_query

        if transport == "serial":
            return [ProbeCandidate(f"stepfoc+serial://{where.serial_port}?baudrate={UART_BAUD}", order=20)]
        if transport == "can":
            extra = bus_query(options)
            base = f"stepfoc+can://{where.interface}/{where.channel}"
            # Each node gets its own bus connection, so the nodes are asked in parallel.
            return [ProbeCandidate(f"{base}?node={node}{extra}", order=10) for node in range(PROBE_NODES)]
        return []

    def raw_probe(self, transport: str) -> Any:
        if transport != "serial":
            return None
        from grippers.drivers.stepfoc import probe as stepfoc_probe

        from . import RawProbe

        return RawProbe(stepfoc_probe.identify_request())

    def open(self, url: ConnectionURL, profile: ProfileBase | None, settings: Settings) -> MsgGripper:
        assumed = not isinstance(profile, MsgProfile)  # no profile given: the rail length is a guess
        if not isinstance(profile, MsgProfile):
            profile = load_profile(DEFAULT_PROFILE)
        assert isinstance(profile, MsgProfile)
        t = profile.transport
        timeout = settings.positive("timeout", t.timeout_s)
        current_limit = profile.effective_max_current_ma
        connect: Callable[[], _Link]
        if url.transport == "can":
            can = (
                settings.str("interface", url.interface),
                settings.str("channel", url.channel),
                settings.int("bitrate", t.can_bitrate),
                settings.int("node", t.node),
                current_limit,
                timeout,
                settings.int("port", None),
            )
            connect = lambda: _CanLink(*can)  # noqa: E731
        elif url.transport == "serial":
            uart = (url.serial_port or "", settings.int("baudrate", t.baudrate), current_limit, timeout)
            connect = lambda: _UartLink(*uart)  # noqa: E731
        else:
            raise URLError(f"{url.url}: the STEPFOC family runs on can or serial, not {url.transport}")
        settings.check()  # a misspelt setting (nod=3) is refused before the bus is opened or polled
        link = connect()
        try:
            link.status()  # is anything there? a silent node raises GripperTimeout naming it
            return MsgGripper(link, profile, url.url, timeout=timeout, profile_assumed=assumed)
        except BaseException:
            link.close()
            raise

    def sim_model(self, profile: ProfileBase, node: int, part_width_mm: float | None) -> Any:
        """A simulated MSG on ``node`` with the profile's travel and a part of ``part_width_mm``."""
        from grippers.drivers.stepfoc.sim import MsgModel

        assert isinstance(profile, MsgProfile)
        sim = profile.simulator
        return MsgModel(
            node=node,
            travel_mm=profile.maps.open_width_mm - profile.maps.closed_width_mm,
            part_width_mm=part_width_mm,
            driver=profile.maps.driver,  # the one speed model: the profile's map is the simulator's
            ticks_per_mm=profile.maps.ticks_per_mm,
            hardware_version=sim.hardware_version,
            software_version=sim.software_version,
            serial=sim.serial,
        )

    def serve(self, models: list[Any], listen: str, settings: Settings) -> Any:
        from grippers.drivers.stepfoc.sim import serve_can, serve_uart

        assert models
        time_scale = settings.positive("time_scale", 1.0)
        if listen == "pty":
            if len(models) != 1:
                raise URLError("a UART simulator serves one gripper")
            return serve_uart(models[0], "pty", time_scale=time_scale)
        return serve_can(models, listen, time_scale=time_scale)

    def simulator(self, profile: ProfileBase, settings: Settings, listen: str | None = None) -> Any:
        assert isinstance(profile, MsgProfile)
        node = settings.int("node", profile.transport.node)
        settings.add_defaults({"time_scale": str(profile.simulator.time_scale)})
        part = settings.float("part_width_mm", profile.simulator.part_width_mm)
        model = self.sim_model(profile, node, part)
        if listen is None:
            transport = settings.str("transport", "can")
            if transport == "can":
                listen = f"can://virtual/grippers-sim-{uuid.uuid4().hex[:12]}"
                settings.add_defaults({"node": str(node)})  # the client talks to the node it simulates
            elif transport in ("pty", "serial"):
                listen = "pty"
            else:
                raise URLError(f"{settings.url}: transport must be can or pty, not {transport!r}")
        return self.serve([model], listen, settings)

    def simulate(self, profile: ProfileBase, settings: Settings) -> Any:
        return self.simulator(profile, settings)
