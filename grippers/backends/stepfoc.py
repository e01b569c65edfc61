"""The MSG-on-STEPFOC backend: the SI map over the driver's device object (drivers/stepfoc/device.py).

The driver knows no millimetres: position 0 is fully open and 255 fully closed between the calibrated end
stops, speed is a byte, and force is only a current limit. :class:`MsgDevice` turns widths, speeds and
newtons into those numbers with the profile's maps, once, and the driver's
:class:`~grippers.drivers.stepfoc.device.StepfocDevice` does the rest on either link (CAN or UART): the poll
loop and its one motion-end rule, the supersede counter, the shared CAN bus. The gripper
(:class:`~grippers.gripper.Gripper`) does the limits, the motion rule and the "jaws start inside
the part" opening before a grasp.
"""

from __future__ import annotations

import contextlib
import time
import uuid
from collections.abc import Callable, Iterator
from functools import cached_property
from typing import TYPE_CHECKING, Any

from grippers.drivers.errors import CommandFailed
from grippers.drivers.stepfoc.can_protocol import Detection
from grippers.drivers.stepfoc.device import (
    FAST_STOP,
    NOT_CALIBRATED,
    CanLink,
    Link,
    Status,
    StepfocDevice,
    UartLink,
    stall_seconds,
)
from grippers.drivers.stepfoc.speed import speed_byte_for, variant

from ..device import Device, DeviceContext, StartedRead, StateCallback
from ..errors import FastStopActive, MotionBlocked, NotReferenced, URLError
from ..gripper import Gripper
from ..profiles import Limits, ProfileBase, load_profile
from ..settings import Settings
from ..states import Capability, DeviceInfo, GraspResult, GraspState, GripperState, MotionResult
from ..urls import ConnectionURL
from .command_hooks import CommandHooks
from .stepfoc_features import MsgReconnection, MsgServo, MsgTemperature
from .stepfoc_profile import MsgProfile

if TYPE_CHECKING:
    import asyncio

DEFAULT_PROFILE = "msg-150"  # the MSG cannot report its rail length: profile= chooses another
CALIBRATION_BOUND_S = 65.0  # a calibration drives both ways at low current, pauses, and may run twice


class MsgDevice(Device):
    """One MSG in SI units over a :class:`StepfocDevice`."""

    # The e-stop is the device's own latch: its bit (UART Gripinfo) or error (CAN 60 flag / frame 26) stays
    # until acknowledge() clears it, and read_state() reports it as the "fast_stop" fault, also when another
    # program raised it. So the gripper takes the device's word.
    reports_fast_stop = True

    def __init__(self, link: Link, profile: MsgProfile, url: str, *, profile_assumed: bool = False) -> None:
        self.profile = profile
        self.url = url
        self.maps = profile.maps
        self.msg = StepfocDevice(link, where=lambda position: f"{self.width_of(position) * 1000:.1f} mm")
        self.profile_assumed = profile_assumed
        self.capabilities = frozenset({Capability.CURRENT_CONTROL, Capability.CALIBRATION}) | (
            {Capability.TEMPERATURE} if link.has_temperature else set()
        )
        self.grips_from_inside = self.maps.inside_grip
        self.temperature = MsgTemperature(self.msg) if link.has_temperature else None
        self.reconnection = MsgReconnection(self)
        self.servo = MsgServo(self)
        self._limits = self.narrow_limits(profile.limits())  # what the gripper enforces (it asks the same)
        self.mode = "idle"  # what the last motion was, to name what the detection bits mean
        self.held = False  # a grasp found its part; detection 3 afterwards means the part was lost

    def bind(self, context: DeviceContext) -> None:
        super().bind(context)
        self.msg.name = context.name
        self.msg.closed = context.closed

    @property
    def driver(self) -> Any:
        return self.msg.driver

    # -- unit maps (profile maps; docs/protocols.md §2 for the byte meanings) --------------------------------

    def position_byte(self, width: float) -> int:
        m = self.maps
        span = m.open_width_mm - m.closed_width_mm
        return max(0, min(255, round((m.open_width_mm - width * 1000) / span * 255)))

    def width_of(self, position: int) -> float:
        m = self.maps
        return (m.open_width_mm - position / 255 * (m.open_width_mm - m.closed_width_mm)) / 1000

    def speed_byte(self, speed: float) -> int:
        # the one speed model (drivers/stepfoc/speed.py): the fastest byte not faster than asked
        m = self.maps
        return speed_byte_for(speed * 1000, m.ticks_per_mm, variant(m.driver))

    def current_ma(self, force: float | None) -> int:
        """The force's current limit: encoded here, once. The gripper checked the force against
        :meth:`limits`, which are the forces of the current range, so nothing is clamped."""
        return (
            self.maps.default_current_ma if force is None else round(force / self.maps.newton_per_amp * 1000)
        )

    def narrow_limits(self, limits: Limits) -> Limits:
        # Force is a current limit here: the forces between the stable minimum current and the (safety)
        # current limit, so a force outside is a LimitError up front instead of a silent change.
        npa = self.maps.newton_per_amp
        return limits.model_copy(
            update={
                "max_force": min(limits.max_force, self.profile.effective_max_current_ma / 1000 * npa),
                "min_force": max(limits.min_force, self.maps.min_current_ma / 1000 * npa),
            }
        )

    def motion_timeout(self, default: float) -> float:
        return max(default, CALIBRATION_BOUND_S)

    # -- motions ---------------------------------------------------------------------------------------

    @contextlib.contextmanager
    def _named(self) -> Iterator[None]:
        """The driver's words for an e-stop and a lost calibration, as the library's errors."""
        try:
            yield
        except CommandFailed as exc:
            if exc.status_name == FAST_STOP:
                raise FastStopActive(exc.message, device=self.name, command=exc.command) from exc
            if exc.status_name == NOT_CALIBRATED:
                raise NotReferenced(device=self.name, command=exc.command) from exc
            raise

    def _go(self, command: str, width: float, speed: float, current_ma: int, timeout: float) -> Status:
        m = self.maps
        step_s = (m.open_width_mm - m.closed_width_mm) / 1000 / 255 / max(speed, 1e-6)
        with self._named():
            self.msg.require_calibrated(command)
            return self.msg.go(
                command,
                self.position_byte(width),
                self.speed_byte(speed),
                current_ma,
                timeout,
                stall_s=stall_seconds(step_s),
            )

    def home(self, timeout: float) -> None:
        self.mode, self.held = "home", False
        with self._named():
            self.msg.calibrate(timeout)
        self.mode = "idle"

    def move(self, width: float, speed: float, timeout: float) -> MotionResult:
        self.mode, self.held = "move", False
        st = self._go("move", width, speed, self.maps.default_current_ma, timeout)
        self._blocked("move", st, width)
        return MotionResult(self.width_of(st.position), self._grasp_state(st))

    def grasp(self, width: float, speed: float, force: float, timeout: float) -> GraspResult:
        # The gripper opened past the part first if the jaws started inside it (Gripper.grasp).
        m = self.maps
        travel = m.grasp_travel_mm / 1000
        target = width + travel if m.inside_grip else width - travel
        target = min(max(target, self._limits.min_width), self._limits.max_width)
        self.mode, self.held = "grasp", False
        current = self.current_ma(force)
        st = self._go("grasp", target, speed, current, timeout)
        expected = Detection.OPENING_OBJECT if m.inside_grip else Detection.CLOSING_OBJECT
        held = st.detection == expected
        self.held = held
        at = self.width_of(st.position)
        return GraspResult(
            held,
            at,
            current / 1000 * m.newton_per_amp if held else None,
            GraspState.HOLDING if held else GraspState.NO_PART,
            reason=None if held else f"reached {at * 1000:.1f} mm without meeting a part",
        )

    def release(self, width: float, speed: float, timeout: float) -> MotionResult:
        self.mode, self.held = "release", False
        st = self._go("release", width, speed, self.maps.default_current_ma, timeout)
        self._blocked("release", st, width)
        self.mode = "idle"
        return MotionResult(self.width_of(st.position), GraspState.IDLE)

    def _blocked(self, command: str, st: Status, target: float) -> None:
        """A move or release that ended on an object short of its target is :class:`MotionBlocked` (it
        returned success with state HOLDING, issue 31 §1). The firmware keeps pushing with the motion's
        current until the next command; the error says where the jaws stand."""
        short = abs(self.width_of(st.position) - target) > MotionBlocked.MARGIN
        if short and st.detection in (Detection.CLOSING_OBJECT, Detection.OPENING_OBJECT):
            raise MotionBlocked(
                width=self.width_of(st.position), target=target, device=self.name, command=command
            )

    def stop(self) -> None:
        self.msg.halt()
        self.mode = "idle"

    def fast_stop(self) -> None:
        self.msg.estop()

    def acknowledge(self) -> None:
        self.msg.clear()

    # -- state -----------------------------------------------------------------------------------------

    def _grasp_state(self, st: Status) -> GraspState:
        if st.estop or st.faults:
            return GraspState.ERROR
        if st.detection == Detection.MOVING and st.activated and st.action:
            return {"grasp": GraspState.GRASPING, "release": GraspState.RELEASING}.get(
                self.mode, GraspState.POSITIONING
            )
        if st.detection in (Detection.CLOSING_OBJECT, Detection.OPENING_OBJECT):
            return GraspState.HOLDING
        if self.mode == "grasp" and st.detection == Detection.AT_POSITION:
            return GraspState.PART_LOST if self.held else GraspState.NO_PART
        return GraspState.IDLE

    def read_state(self) -> GripperState:
        return self._state_of(self.msg.status())

    def start_read(self, done: StateCallback) -> StartedRead | None:
        # CAN only: the UART client reads its replies on the calling thread (a worker reads it instead)
        def finished(st: Status | None, error: BaseException | None) -> None:
            if st is None:
                done(None, error)
                return
            try:
                state = self._state_of(st)
            except Exception as exc:  # noqa: BLE001 - handed to the caller: done is called once, always
                done(None, exc)
                return
            done(state, None)

        cancel = self.msg.start_status(finished)
        # The bus times each request out itself (its reader's clock), so no caller timer: the poll and the
        # error-cause read end as the threaded call's do, frame 26 unanswered included ("error").
        return None if cancel is None else StartedRead(cancel, None)

    def _state_of(self, st: Status) -> GripperState:
        """The state a status read says, whichever face read it."""
        return GripperState(
            width=self.width_of(st.position),
            speed=None,
            force=None,
            current=None if st.current_ma is None else abs(st.current_ma) / 1000,
            grasp=self._grasp_state(st),
            moving=self.msg.moving(st),
            referenced=st.calibrated,
            faults=st.faults,
            timestamp=time.time(),
        )

    def info(self) -> DeviceInfo:
        ident = self.msg.link.identity()
        extra: dict[str, Any] = ident["extra"]
        if self.profile_assumed:
            warning = (
                f"model {self.profile.name} assumed (the MSG cannot report its rail length); pass a profile"
            )
            extra = {**extra, "warnings": [*extra.get("warnings", []), warning]}
        return DeviceInfo(
            family="stepfoc",
            vendor=self.profile.vendor,
            model=self.profile.model,
            serial=ident["serial"],
            firmware=ident["firmware"],
            hardware=ident["hardware"],
            limits=self._limits,
            url=self.url,
            profile=self.profile.name,
            extra=extra,
        )

    def close(self) -> None:
        self.msg.close()

    # -- hooks of the contract -------------------------------------------------------------------------

    def read_on(self, loop: asyncio.AbstractEventLoop) -> Callable[[], None] | None:
        return self.msg.read_on(loop)

    def abandon(self, thread_ident: int) -> None:
        self.msg.abandon(thread_ident)

    def resume(self, thread_ident: int) -> None:
        self.msg.resume(thread_ident)


class StepfocBackend:
    family = "stepfoc"
    profile_model = MsgProfile

    @cached_property
    def commands(self) -> CommandHooks:
        """What the commands ask of the family (stepfoc_cli.py, imported when a command asks)."""
        from .stepfoc_cli import StepfocCommands

        return StepfocCommands()

    def open(self, url: ConnectionURL, profile: ProfileBase | None, settings: Settings) -> Gripper:
        assumed = not isinstance(profile, MsgProfile)  # no profile given: the rail length is a guess
        if not isinstance(profile, MsgProfile):
            profile = load_profile(DEFAULT_PROFILE)
        assert isinstance(profile, MsgProfile)
        t = profile.transport
        timeout = settings.positive("timeout", t.timeout_s)
        current_limit = profile.effective_max_current_ma
        connect: Callable[[], Link]
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
            connect = lambda: CanLink(*can)  # noqa: E731
        elif url.transport == "serial":
            uart = (url.serial_port or "", settings.int("baudrate", t.baudrate), current_limit, timeout)
            connect = lambda: UartLink(*uart)  # noqa: E731
        else:
            raise URLError(f"{url.url}: the STEPFOC family runs on can or serial, not {url.transport}")
        settings.check()  # a misspelt setting (nod=3) is refused before the bus is opened or polled
        link = connect()
        try:
            link.status()  # is anything there? a silent node raises GripperTimeout naming it
            device = MsgDevice(link, profile, url.url, profile_assumed=assumed)
            return Gripper(device, profile, url.url, timeout=timeout)
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
