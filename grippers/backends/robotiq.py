"""The Robotiq backend: 2F-85, 2F-140 and Hand-E over Modbus RTU (an RS-485 adapter, or a UR robot's
tool-communication forwarder on TCP), on :class:`grippers.drivers.robotiq.client.RobotiqClient`.

Units change here and nowhere else: the device speaks bytes (position, speed and force 0..255), the profile's
``robotiq`` section maps them to mm (per unit: its own open and closed counts), mm/s and N (approximate: the
grip force also depends on the speed, the fingers and the part; docs/protocols-robotiq.md §2).

The semantics on the common interface (docs/getting-started-robotiq.md says the same to users):

- ``home()`` activates a gripper that is not active: rACT cleared, then set, and a bounded wait for gSTA
  "activation completed" (the sweep opens and closes the fingers). On an active, fault-free gripper it sends
  nothing and returns: clearing rACT would release a held part and sweep the whole stroke, and the gripper
  needs no referencing once active. A re-activation is needed only after a major fault (``acknowledge()``
  clears it, then ``home()`` activates) or a power cycle (the gripper then reports itself not active).
- ``move``/``grasp``/``release`` write rPR, rSP, rFR with rGTO set and poll the status until gOBJ leaves 0;
  ``grasp()`` is held on gOBJ 2 (contact while closing) or 1 (contact while opening), no part on gOBJ 3.
- ``stop()`` clears rGTO: the fingers halt where they are; on a gripper that is not activated it writes
  nothing (rACT written 1 would start the activation's sweep: a stop never starts a motion). ``fast_stop()``
  does the same, since the device has no brake or e-stop input of its own (the automatic release, rATR/rARD,
  is a slow opening or closing, not a stop); the gripper holding the device latches it until
  ``acknowledge()`` (``reports_fast_stop`` False; ``info().extra["fast_stop"]`` says so).
- ``acknowledge()`` clears the gripper's fast-stop latch and, after a major fault (0x0A-0x0F), clears the
  fault with the first half of the manual's reset (rACT cleared), which moves nothing; ``home()`` then
  activates (rACT set), which sweeps the fingers. An acknowledgement never starts a motion (issue 40 §5).
- a newer motion is written over the running one (rPR with rGTO set, no stop in between:
  ``moves_to_new_targets``); the older motion's wait ends "superseded" (a new epoch of
  :class:`grippers.kit.motion.MotionEpochs`).
- a motion before the activation raises :class:`~grippers.NotReferenced` at once, not a timeout; a move
  stopped by an obstacle short of its target raises :class:`~grippers.MotionBlocked`, as on every family.
"""

from __future__ import annotations

import logging
import time
from collections.abc import Callable
from functools import cached_property
from typing import TYPE_CHECKING, Any

from grippers.drivers.errors import CommandFailed
from grippers.drivers.robotiq.client import RobotiqClient
from grippers.drivers.robotiq.registers import (
    DEFAULT_SLAVE,
    MAJOR_FAULTS,
    URCAP_PORT,
    ActivationState,
    Command,
    Fault,
    ObjectDetection,
    Status,
    fault_name,
    fault_text,
)
from grippers.drivers.robotiq.session import FaultClass, MotionTracker, classify_fault
from grippers.drivers.robotiq.urcap import UrcapClient

from ..device import Device
from ..errors import MotionBlocked, NotReferenced, URLError
from ..gripper import Gripper
from ..kit.motion import MotionEpochs, poll_until
from ..profiles import ProfileBase
from ..states import Capability, DeviceInfo, GraspResult, GraspState, GripperState, MotionResult
from .command_hooks import CommandHooks
from .robotiq_profile import FALLBACK_PROFILE, RobotiqProfile

if TYPE_CHECKING:
    from ..servo import ServoTarget
    from ..settings import Settings
    from ..urls import ConnectionURL

log = logging.getLogger(__name__)


# -- errors: the lead maps these two onto the library-wide classes when they land (one line each) ----------


def not_activated_error(message: str, *, device: str, command: str) -> NotReferenced:
    """A motion before activation: the library's one error for a motion before ``home()`` (issue 31 §1)."""
    return NotReferenced(message, status_name="not_activated", device=device, command=command)


class RobotiqFault(CommandFailed):
    """The gripper reports a fault (gFLT): ``status`` is the code, ``status_name`` its name."""


def fault_error(st: Status, *, device: str, command: str, url: str = "URL") -> CommandFailed | None:
    """The typed error for the fault ``st`` shows, or None where the wait goes on (a delayed action, the
    watchdog's note, which the next write clears): drivers/robotiq/session.py classifies. The next step is
    told in the user's terms, the command line's (``grippers ack URL``), with the Python call beside it."""
    kind = classify_fault(st.fault)
    if kind in (FaultClass.NONE, FaultClass.TRANSIENT):
        return None
    if kind is FaultClass.NOT_ACTIVATED:
        return not_activated_error(
            f"the gripper is not activated (gFLT 0x07): activate it with `grippers home {url}` "
            "(home() in Python; the fingers sweep the stroke)",
            device=device,
            command=command,
        )
    hint = (
        f": clear it with `grippers ack {url}` (acknowledge() in Python), then `grippers home {url}` "
        "re-activates (the fingers sweep the stroke)"
        if kind is FaultClass.MAJOR
        else ""
    )
    return RobotiqFault(
        f"gripper fault 0x{st.fault:02X}: {fault_text(st.fault)}{hint}",
        status=st.fault,
        status_name=fault_name(st.fault),
        device=device,
        command=command,
    )


# -- the device ----------------------------------------------------------------------------------------------


class RobotiqDevice(Device):
    """One Robotiq gripper over a :class:`RobotiqClient` (Modbus RTU) or a :class:`UrcapClient`, in SI units.

    The gripper that holds it (:class:`~grippers.gripper.Gripper`) checks limits, runs the motion
    rule and keeps the fast-stop latch (``reports_fast_stop`` False: the device has no fast-stop state). The
    device takes a new rPR mid-motion (``moves_to_new_targets``): a newer motion is written over the running
    one without a stop, and :meth:`supersede` only ends the older wait (a new motion epoch).
    """

    capabilities = frozenset({Capability.CURRENT_CONTROL, Capability.CALIBRATION})
    reports_fast_stop = False
    moves_to_new_targets = True

    def __init__(
        self,
        client: RobotiqClient | UrcapClient,
        profile: RobotiqProfile,
        url: str,
        *,
        timeout: float,
        connect: Callable[[], RobotiqClient | UrcapClient] | None = None,
        profile_assumed: bool = False,
    ) -> None:
        self.client = client
        self.profile_assumed = profile_assumed  # no profile named: the registers do not say the model
        self.profile = profile
        self.url = url
        self.maps = profile.robotiq
        self.limits = profile.limits()
        self.timeout = timeout
        self.epochs = MotionEpochs()  # a newer motion or a stop ends older waits (grippers.kit.motion)
        self._last = Command()  # the request block as last written (its speed and force persist)
        self._mode = "idle"
        self._held = False
        self.reconnection = None if connect is None else RobotiqReconnection(self, connect)
        self.servo = RobotiqServo(self)

    @property
    def driver(self) -> RobotiqClient | UrcapClient:
        return self.client

    # -- faults and waits ----------------------------------------------------------------------------------

    def _ready(self, command: str) -> Status:
        """The status before a motion: activated and without a fault, or a clear error."""
        st = self.client.read_status(command=command)
        error = fault_error(st, device=self.name, command=command, url=self.url)
        if error is not None:
            raise error
        if not st.activated:
            what = "being activated" if st.sta == ActivationState.IN_PROGRESS else "not activated"
            raise not_activated_error(
                f"the gripper is {what} (gSTA {int(st.sta)}): activate it first with `grippers home "
                f"{self.url}` (home() in Python)",
                device=self.name,
                command=command,
            )
        return st

    def _wait(
        self, command: str, motion: int, timeout: float, done: Callable[[Status], bool], *, activating: bool
    ) -> Status:
        """Poll the status until ``done``: ends early, never as success, on a newer motion or a stop, a fault,
        rGTO or rACT cleared by someone else, close(), or the timeout (grippers.kit.motion.poll_until)."""

        def fault(st: Status) -> CommandFailed | None:
            error = fault_error(st, device=self.name, command=command, url=self.url)
            if error is None and (
                not st.act or (not activating and not (st.gto and st.sta == ActivationState.COMPLETE))
            ):
                error = CommandFailed(
                    f"{command} aborted: rGTO or rACT was cleared (another program?) at "
                    f"{self.profile.width_of(st.position) * 1000:.1f} mm",
                    status_name="aborted",
                    device=self.name,
                    command=command,
                )
            return error

        return poll_until(
            lambda: self.client.read_status(command=command),
            done,
            context=self.context,
            command=command,
            timeout=timeout,
            epochs=self.epochs,
            motion=motion,
            fault=fault,
        )

    def _go(self, command: str, position: int, speed: float, force: float | None, timeout: float) -> Status:
        self._ready(command)
        f = self._last.force if force is None else self.profile.force_byte(force)
        cmd = Command(act=True, gto=True, position=position, speed=self.profile.speed_byte(speed), force=f)
        motion = self.epochs.begin(f"superseded by a newer motion before it ended ({command})")
        self.client.write_command(cmd, command=command)
        self._last = cmd
        m = self.maps
        tracker = MotionTracker(position, time.monotonic(), m.open_count, m.closed_count)
        return self._wait(
            command, motion, timeout, lambda st: tracker.update(st, time.monotonic()), activating=False
        )

    def _activate(self, command: str, motion: int, timeout: float, *, write: bool, reset: bool) -> None:
        """rACT cleared (``reset``: a rising edge is needed), then set (``write``), and a bounded wait for
        gSTA "activation completed"."""
        if reset:
            self.client.write_command(Command(), command=command)
        if write:
            self._last = Command(act=True, speed=self._last.speed, force=self._last.force or 255)
            self.client.write_command(self._last, command=command)
        complete = lambda s: s.sta == ActivationState.COMPLETE  # noqa: E731
        self._wait(command, motion, timeout, complete, activating=True)

    # -- the primitives ------------------------------------------------------------------------------------

    def home(self, timeout: float) -> None:
        st = self.client.read_status(command="home")
        if st.activated and st.fault not in MAJOR_FAULTS and st.fault != Fault.ACTIVATION_BIT:
            return  # active already: nothing is toggled (see the module's docstring)
        if st.fault in MAJOR_FAULTS and st.act:
            error = fault_error(st, device=self.name, command="home", url=self.url)
            assert error is not None
            raise error
        motion = self.epochs.begin("superseded by a newer motion before it ended (home)")
        self._mode, self._held = "home", False
        # An activation under way (one that an earlier home() stopped waiting for) is waited for, not reset:
        # clearing rACT without setting it again would leave the gripper reset (issue 43 §5).
        waiting = st.act and st.sta == ActivationState.IN_PROGRESS and not st.fault
        reset = not waiting and bool(st.act or st.fault)
        self._activate("home", motion, timeout, write=not waiting, reset=reset)
        self._mode = "idle"

    def move(self, width: float, speed: float, timeout: float) -> MotionResult:
        self._mode, self._held = "move", False
        st = self._go("move", self.profile.position_byte(width), speed, None, timeout)
        self._mode = "idle"
        at = self.profile.width_of(st.position)
        contact = st.obj in (ObjectDetection.CONTACT_CLOSING, ObjectDetection.CONTACT_OPENING)
        if contact and abs(at - width) > MotionBlocked.MARGIN:  # the rule every family follows (errors.py)
            raise MotionBlocked(width=at, target=width, status=int(st.obj), device=self.name, command="move")
        return MotionResult(at, GraspState.IDLE)

    def grasp(self, width: float, speed: float, force: float, timeout: float) -> GraspResult:
        m = self.maps
        self._mode, self._held = "grasp", False
        beyond = width * 1000 - m.grasp_travel_mm
        target = 255 if beyond <= m.closed_width_mm else self.profile.position_byte(beyond / 1000)
        st = self._go("grasp", target, speed, force, timeout)
        at = self.profile.width_of(st.position)
        held = st.obj in (ObjectDetection.CONTACT_CLOSING, ObjectDetection.CONTACT_OPENING)
        self._held = held
        if held:
            return GraspResult(True, at, force, GraspState.HOLDING)
        return GraspResult(
            False,
            at,
            None,
            GraspState.NO_PART,
            reason=f"reached {at * 1000:.1f} mm without meeting a part (gOBJ 3)",
        )

    def release(self, width: float, speed: float, timeout: float) -> MotionResult:
        self._mode, self._held = "release", False
        target = 0 if width >= self.limits.max_width else self.profile.position_byte(width)
        st = self._go("release", target, speed, None, timeout)
        self._mode = "idle"
        return MotionResult(self.profile.width_of(st.position), GraspState.IDLE)

    def _halt(self, cause: str, command: str) -> None:
        """rGTO cleared, rACT kept as the device has it: a stop never starts an activation (issue 40 §5: rACT
        written 1 to a gripper that is not active starts the sweep of the whole stroke)."""
        self.epochs.begin(cause)
        last = self._last
        if not last.act:  # nothing written by us yet: the device's own rACT and rPR decide
            st = self.client.read_status(command=command)
            self._mode = "idle"
            if not st.act:
                return  # not activated: nothing moves, and nothing is written
            last = Command(act=True, position=st.position_echo, speed=last.speed, force=last.force)
        cmd = Command(act=True, gto=False, position=last.position, speed=last.speed, force=last.force)
        self.client.write_command(cmd, command=command)
        self._last = cmd
        self._mode = "idle"

    def stop(self) -> None:
        self._halt("aborted by stop()", "stop")

    def fast_stop(self) -> None:
        # No brake and no e-stop input: the same halt; the gripper latches it (reports_fast_stop False).
        self._halt("aborted by fast_stop()", "fast_stop")

    def supersede(self) -> None:
        # The gripper takes a new target mid-motion (rPR rewritten with rGTO set): no stop in between.
        self.epochs.begin("superseded by a newer motion before it ended")

    def acknowledge(self) -> None:
        st = self.client.read_status(command="acknowledge")
        if st.fault not in MAJOR_FAULTS:
            return  # the fast-stop latch is the gripper's: nothing to clear on the device
        # The reset half of the manual's cure (rACT cleared): it clears the fault and moves nothing. The
        # activation (rACT set), which sweeps the stroke, is home()'s: an acknowledgement never starts a
        # motion (issue 40 §5).
        log.warning("%s: fault 0x%02X cleared (rACT 0): home() re-activates", self.name, st.fault)
        self.epochs.begin("aborted by acknowledge()")
        self._last = Command(speed=self._last.speed, force=self._last.force)
        self.client.write_command(self._last, command="acknowledge")
        self._mode = "idle"

    # -- state and info ----------------------------------------------------------------------------------

    def _grasp_state(self, st: Status) -> GraspState:
        if st.fault in MAJOR_FAULTS:
            return GraspState.ERROR
        if st.moving:
            return {"grasp": GraspState.GRASPING, "release": GraspState.RELEASING}.get(
                self._mode, GraspState.POSITIONING
            )
        if st.gto and st.obj in (ObjectDetection.CONTACT_CLOSING, ObjectDetection.CONTACT_OPENING):
            return GraspState.HOLDING
        if self._mode == "grasp" or (self._held and st.gto and st.obj == ObjectDetection.AT_POSITION):
            return GraspState.PART_LOST if self._held else GraspState.NO_PART
        return GraspState.IDLE

    def read_state(self) -> GripperState:
        st = self.client.read_status(command="state")
        return GripperState(
            width=self.profile.width_of(st.position),
            speed=None,
            force=None,
            current=None if st.current_ma is None else st.current_ma / 1000,
            grasp=self._grasp_state(st),
            moving=st.moving,
            referenced=st.activated,
            faults=(fault_name(st.fault),) if st.fault else (),
            timestamp=time.time(),
        )

    def info(self) -> DeviceInfo:
        p = self.profile
        st = self.client.read_status(command="info")
        warnings = [assumed_warning(p.name, self.url)] if self.profile_assumed else []
        return DeviceInfo(
            family="robotiq",
            vendor=p.vendor,
            model=p.model,
            serial=None,  # not in the documented registers
            firmware=None,
            hardware=None,
            limits=self.limits,
            url=self.url,
            profile=p.name,
            extra={
                "slave": self.client.slave,
                "activated": st.activated,
                "status": st.describe(),
                "force": "approximate: rFR 0..255 mapped linearly onto the profile's force range",
                "fast_stop": "rGTO cleared (the device has no brake); the library refuses motion until "
                "acknowledge()",
                **({"warnings": warnings} if warnings else {}),
            },
        )

    def close(self) -> None:
        self.client.close()


class RobotiqReconnection:
    """``reconnect=true``: a fresh link on the same URL (the connector ``RobotiqBackend.open`` built)."""

    def __init__(self, device: RobotiqDevice, connect: Callable[[], RobotiqClient | UrcapClient]) -> None:
        self._device = device
        self._connect = connect

    def alive(self) -> bool:
        return self._device.client.alive

    def identity(self) -> dict[str, str]:
        return {}  # no serial number in the documented registers: units cannot be told apart

    def reconnect(self) -> None:
        old = self._device.client
        if old.alive:
            new = old  # the link never broke (a serial line): the device answering again is the reconnection
        else:
            old.close()  # a serial port must be free before it is opened again
            new = self._connect()
        try:
            new.read_status(command="reconnect")
        except BaseException:
            if new is not old:
                new.close()
            raise
        self._device.client = new


class RobotiqServo:
    """``servo()``: a stream of rPR targets written with rGTO set, without waiting for each motion's end."""

    def __init__(self, device: RobotiqDevice) -> None:
        self._device = device

    def begin(self) -> None:
        self._device._ready("servo")
        self._device._mode = "move"

    def send(self, target: ServoTarget) -> bool | None:
        d = self._device
        force = d._last.force if target.force is None else d.profile.force_byte(target.force)
        cmd = Command(
            act=True,
            gto=True,
            position=d.profile.position_byte(target.width),
            speed=d.profile.speed_byte(target.speed),
            force=force,
        )
        if cmd == d._last:
            return False
        d.client.write_command(cmd, command="servo")
        d._last = cmd
        return True

    def end(self) -> None:
        self._device._mode = "idle"


def assumed_warning(profile: str, url: str) -> str:
    """What ``info()`` says when no profile was named (issue 39 §1: a Hand-E taken for a 2F-85 reads 85 mm of
    stroke for its 50 mm, with no word said)."""
    return (
        f"model {profile} assumed: the Robotiq registers do not say which gripper answers (a 2F-85, 2F-140 "
        f"or Hand-E); name it: `grippers state {url} --profile robotiq-hande` (robotiq-2f85, "
        "robotiq-2f140), profile= in Python"
    )


def robotiq_gripper(
    client: RobotiqClient | UrcapClient,
    profile: RobotiqProfile,
    url: str,
    *,
    timeout: float,
    connect: Callable[[], RobotiqClient | UrcapClient] | None = None,
    profile_assumed: bool = False,
) -> Gripper:
    """The gripper over an open ``client``: what :meth:`RobotiqBackend.open` returns (``connect``: how to
    reopen the link for ``reconnect=true``; None, no reconnection; ``profile_assumed``: no profile was named,
    ``grippers.open`` warns). Tests and benchmarks build one over a scripted client with it."""
    device = RobotiqDevice(
        client, profile, url, timeout=timeout, connect=connect, profile_assumed=profile_assumed
    )
    return Gripper(device, profile, url, timeout=timeout)


class RobotiqBackend:
    family = "robotiq"
    profile_model = RobotiqProfile
    url_protocols = {"urcap": "tcp"}  # robotiq+urcap://HOST[:63352]: the URCap socket (grippers/api.py)

    @cached_property
    def commands(self) -> CommandHooks:
        """What the commands ask of the family (robotiq_cli.py, imported when a command asks)."""
        from .robotiq_cli import RobotiqCommands

        return RobotiqCommands()

    def open(self, url: ConnectionURL, profile: ProfileBase | None, settings: Settings) -> Gripper:
        from ..profiles import load_profile

        assumed = profile is None  # the registers do not name the model: the fallback is a guess
        if profile is None:
            profile = load_profile(FALLBACK_PROFILE)
        if not isinstance(profile, RobotiqProfile):
            raise URLError(f"{url.url}: profile {profile.name!r} is not a Robotiq profile")
        t = profile.transport
        common = {
            "timeout": settings.positive("timeout", t.timeout_s),
            "slave": settings.int("slave", t.slave),
            "read_function": settings.int("read_function", t.read_function),
        }
        if not 1 <= common["slave"] <= 247:
            raise URLError(f"{url.url}: slave must be 1..247, not {common['slave']}")
        if common["read_function"] not in (3, 4):
            raise URLError(f"{url.url}: read_function must be 3 or 4")
        # Every setting is taken once, here; reconnection reuses this connector (never a re-parse of the URL).
        # The URCap's ASCII socket is TCP too: robotiq+urcap://, port 63352 or ?protocol=urcap selects it.
        protocol = settings.str("protocol", "urcap" if url.port == URCAP_PORT else "rtu")
        if protocol not in ("rtu", "urcap") or (protocol == "urcap" and url.transport != "tcp"):
            raise URLError(f"{url.url}: protocol must be rtu, or urcap over tcp, not {protocol!r}")
        connect: Callable[[], RobotiqClient | UrcapClient]
        if url.transport == "serial":
            port, baudrate = url.serial_port, settings.int("baudrate", t.baudrate)
            if not port:
                raise URLError(f"{url.url}: a serial URL needs a port")
            connect = lambda: RobotiqClient.serial(port, baudrate=baudrate, device=url.url, **common)  # noqa: E731
        elif url.transport == "tcp":
            host = url.host
            if not host:
                raise URLError(f"{url.url}: a tcp URL needs a host")
            if protocol == "urcap":
                urcap_port, timeout, slave = url.port or URCAP_PORT, common["timeout"], common["slave"]
                connect = lambda: UrcapClient(  # noqa: E731
                    host, urcap_port, device=url.url, timeout=timeout, slave=slave
                )
            else:
                tcp_port = url.port or t.tcp_port
                connect = lambda: RobotiqClient.tcp(host, tcp_port, device=url.url, **common)  # noqa: E731
        else:
            raise URLError(
                f"{url.url}: robotiq speaks over serial or tcp (a forwarder or the URCap), "
                f"not {url.transport!r}"
            )
        client = connect()
        try:
            client.read_status(command="open")  # a gripper answers, or the open fails here
            return robotiq_gripper(
                client, profile, url.url, timeout=common["timeout"], connect=connect, profile_assumed=assumed
            )
        except BaseException:
            client.close()
            raise

    def simulator(self, profile: ProfileBase, settings: Settings, listen: str | None = None) -> Any:
        """A simulated unit of ``profile`` serving on ``listen`` (default: loopback TCP, a free port)."""
        from grippers.drivers.robotiq.sim import ModelParams, RobotiqModel, serve

        assert isinstance(profile, RobotiqProfile)
        m, r, sim = profile.mechanics, profile.robotiq, profile.simulator
        params = ModelParams(
            model=profile.model,
            open_width_mm=r.open_width_mm,
            closed_width_mm=r.closed_width_mm,
            open_count=r.open_count,
            closed_count=r.closed_count,
            min_speed_mm_s=m.min_speed_mm_s,
            max_speed_mm_s=m.max_speed_mm_s,
            activation_s=settings.positive("activation_s", sim.activation_s),
            slave=settings.int("slave", profile.transport.slave),
            watchdog_s=settings.float("watchdog_s", sim.watchdog_s),
        )
        model = RobotiqModel(params, part_width_mm=settings.float("part_width_mm", sim.part_width_mm))
        if settings.bool("activated", sim.activated):
            model.act, model.sta = True, ActivationState.COMPLETE
            model.command = Command(act=True)
        transport = settings.str("transport", "tcp")
        if listen is None:
            listen = {
                "tcp": "tcp://127.0.0.1:0",
                "pty": "pty",
                "serial": "pty",
                "urcap": "urcap://127.0.0.1:0",
            }.get(transport)
            if listen is None:
                raise URLError(f"{settings.url}: transport must be tcp, pty or urcap, not {transport!r}")
        server = serve(model, listen, time_scale=settings.positive("time_scale", sim.time_scale))
        if params.slave != DEFAULT_SLAVE:
            server.url += f"{'&' if '?' in server.url else '?'}slave={params.slave}"
        return server
