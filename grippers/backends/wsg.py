"""The WSG backend: :class:`WsgDevice`, a :class:`grippers.device.Device` over a WSG client, in SI units.

:meth:`WsgBackend.open` returns the :class:`~grippers.device_gripper.DeviceGripper` holding it.

The driver speaks mm, mm/s and N; the conversion happens here and nowhere else. The device's own Get System
Limits (53h) answer narrows the profile's limits at connect time, so a profile with optimistic datasheet
numbers cannot send a value the gripper would turn into a FAST STOP.
"""

from __future__ import annotations

import logging
import math
import time
import uuid
from collections.abc import Callable, Iterator
from contextlib import contextmanager
from typing import TYPE_CHECKING, Any

from grippers.drivers.errors import CommandFailed, GripperError
from grippers.drivers.wsg.client import WsgClient
from grippers.drivers.wsg.commands import (
    Cmd,
    GraspingState,
    SystemFlags,
    SystemInfo,
    SystemLimits,
    available,
)
from grippers.drivers.wsg.protocol import Status

from ..device import Device, StartedRead, StateCallback
from ..device_gripper import DeviceGripper
from ..errors import MotionBlocked, NotReferenced, URLError
from ..profiles import Limits, ProfileBase, load_profile
from ..settings import Settings
from ..states import Capability, DeviceInfo, GraspResult, GraspState, GripperState, MotionResult
from ..urls import ConnectionURL
from .wsg_profile import WsgProfile, WsgTransport, wsg_profile_for_device_type

if TYPE_CHECKING:
    from ..servo import ServoTarget

# WSG grasping states (manual 4.0.x §3.4.2) onto the common enum: the names match one to one.
_GRASP: dict[int, GraspState] = {
    GraspingState.IDLE: GraspState.IDLE,
    GraspingState.GRIPPING: GraspState.GRASPING,
    GraspingState.NO_PART: GraspState.NO_PART,
    GraspingState.PART_LOST: GraspState.PART_LOST,
    GraspingState.HOLDING: GraspState.HOLDING,
    GraspingState.RELEASING: GraspState.RELEASING,
    GraspingState.POSITIONING: GraspState.POSITIONING,
    GraspingState.ERROR: GraspState.ERROR,
}

# System-state flags that are faults (manual Appendix B), reported by name without the SF_ prefix.
_FAULT_FLAGS = tuple(
    flag
    for flag in SystemFlags
    if flag.name and any(word in flag.name for word in ("FAST_STOP", "FAULT", "FAILURE", "WARNING"))
)

FALLBACK_PROFILE = "wsg50"

log = logging.getLogger(__name__)


def _fault_names(flags: int) -> tuple[str, ...]:
    return tuple(f.name.removeprefix("SF_").lower() for f in _FAULT_FLAGS if flags & f and f.name)


# What a state is read from, in this order (threaded and asyncio alike): system state, grasping state, width,
# speed, force (WSG manual 4.0.x §3.4).
_STATE_READS = (
    Cmd.GET_SYSTEM_STATE,
    Cmd.GET_GRASPING_STATE,
    Cmd.GET_WIDTH,
    Cmd.GET_SPEED,
    Cmd.GET_FORCE,
)


def _state_of(values: list[Any]) -> GripperState:
    """The state from the values of :data:`_STATE_READS` (mm, mm/s, N in; SI out)."""
    system, grasping, width, speed, force = values
    flags = int(system)
    return GripperState(
        width=width / 1000,
        speed=speed / 1000,
        force=force,
        current=None,
        grasp=_GRASP.get(grasping, GraspState.ERROR),
        moving=bool(flags & SystemFlags.SF_MOVING),
        referenced=bool(flags & SystemFlags.SF_REFERENCED),
        faults=_fault_names(flags),
        timestamp=time.time(),
    )


class WsgDevice(Device):
    """A WSG over a :class:`~grippers.drivers.wsg.client.WsgClient`, in SI units (the contract's primitives).

    The device latches its own FAST STOP and reports it in the system state (SF_FAST_STOP), so the gripper
    takes its word (:attr:`reports_fast_stop`). Optional features are the objects below, each over the
    client in use (a reconnection swaps it in)."""

    reports_fast_stop = True

    def __init__(
        self,
        client: WsgClient,
        profile: WsgProfile,
        url: str,
        *,
        system_info: SystemInfo,
        device_limits: SystemLimits | None,
        connect: Callable[[], WsgClient],
    ) -> None:
        self._client = client
        self.profile = profile
        self.url = url
        self.system_info = system_info
        #: The profile's limits within the device's own 53h answer (the gripper enforces these).
        self.limits = profile.limits()
        #: Human-readable lines for probe/info (``DeviceInfo.extra["warnings"]``).
        self.warnings: list[str] = []
        if device_limits is not None:
            self.limits, self.warnings = _narrow(self.limits, device_limits, profile.name)
            for line in self.warnings:
                log.warning("%s: %s", url, line)
        caps = {
            Capability.FORCE_CONTROL,
            Capability.FORCE_MEASUREMENT,
            Capability.HOMING,
            Capability.SOFT_LIMITS,
            Capability.DEVICE_TAG,
            Capability.PUSH_UPDATES,
        }
        # The command table decides which firmware has 46h and the finger commands (2.x has neither).
        firmware = system_info.firmware
        if available(Cmd.GET_TEMPERATURE, firmware):
            caps.add(Capability.TEMPERATURE)
        if available(Cmd.GET_FINGER1_DATA, firmware):
            caps.add(Capability.FINGER_DATA)
        self.capabilities = frozenset(caps)
        self.reconnection = WsgReconnection(self, connect)
        self._servo = WsgServo(self)
        self.servo = self._servo
        self.soft_limits = WsgSoftLimits(self)
        self.temperature = WsgTemperature(self) if Capability.TEMPERATURE in caps else None
        self.device_tag = WsgDeviceTag(self)

    @property
    def driver(self) -> WsgClient:
        return self._client

    def swap(self, client: WsgClient, system_info: SystemInfo) -> None:
        """A reconnection's new client (and what it reported) replaces the old one."""
        self._client = client
        self.system_info = system_info
        self._servo.reset()

    # -- the primitives (mm, mm/s and N on the wire; m, m/s and N here) ----------------------------------

    def home(self, timeout: float) -> None:
        self._client.home(timeout=timeout)

    @contextmanager
    def _typed(self, command: str, target: float | None = None) -> Iterator[None]:
        """The device's refusals that every family reports alike (issue 31 §1), as their typed errors:
        E_NOT_INITIALIZED (manual 4.0.x §3.2: a motion before homing) is :class:`NotReferenced`, and
        E_AXIS_BLOCKED on a pre-position or release (§3.2.2: the fingers met an obstacle; with stop-on-block
        they stop there) is :class:`MotionBlocked` with the width where they stopped. ``target`` None: a
        grasp, where meeting something is the point (its E_AXIS_BLOCKED, if any, passes unchanged)."""
        try:
            yield
        except CommandFailed as exc:
            kw: dict[str, Any] = {
                "status": exc.status,
                "status_name": exc.status_name,
                "device": self.name,
                "command": command,
            }
            if exc.status == Status.E_NOT_INITIALIZED:
                raise NotReferenced(**kw) from exc
            if exc.status == Status.E_AXIS_BLOCKED and target is not None:
                width = self._client.width() / 1000
                if abs(width - target) <= MotionBlocked.MARGIN:
                    return  # stopped on the part where it was sent: the target was reached
                raise MotionBlocked(width=width, target=target, **kw) from exc
            raise

    def _where(self) -> MotionResult:
        c = self._client
        return MotionResult(c.width() / 1000, _GRASP.get(c.grasping_state(), GraspState.IDLE))

    def move(self, width: float, speed: float, timeout: float) -> MotionResult:
        with self._typed("move", width):
            self._client.preposition(width * 1000, speed * 1000, timeout=timeout)
        return self._where()

    def grasp(self, width: float, speed: float, force: float, timeout: float) -> GraspResult:
        c = self._client
        try:
            with self._typed("grasp"):
                c.grip(width * 1000, speed * 1000, force=force, timeout=timeout)
        except CommandFailed as exc:
            if exc.status != Status.E_CMD_FAILED:
                raise
            # E_CMD_FAILED is the manual's "no part found": an outcome, not an error (§3.2.6).
            return GraspResult(
                False,
                c.width() / 1000,
                None,
                GraspState.NO_PART,
                reason=f"no part found within the clamping travel ({exc.status_name})",
            )
        state = _GRASP.get(c.grasping_state(), GraspState.ERROR)
        held = state is GraspState.HOLDING
        return GraspResult(
            held,
            c.width() / 1000,
            c.force() if held else None,
            state,
            reason=None if held else f"grasping state is {state.value}",
        )

    def release(self, width: float, speed: float, timeout: float) -> MotionResult:
        with self._typed("release", width):
            self._client.release(width * 1000, speed * 1000, timeout=timeout)
        return self._where()

    def stop(self) -> None:
        self._client.stop()

    def fast_stop(self) -> None:
        self._client.fast_stop()

    def acknowledge(self) -> None:
        self._client.acknowledge_fast_stop()

    def fast_stop_latched(self) -> bool:
        # Manual 4.0.x §1.4.2: a TCP connection closed without 07h leaves the gripper in FAST STOP.
        return bool(self._client.system_state() & SystemFlags.SF_FAST_STOP)

    def read_state(self) -> GripperState:
        return _state_of(self._client.queries(_STATE_READS))

    def start_read(self, done: StateCallback) -> StartedRead:
        """The same reads as :meth:`read_state`, sent by callback from the driver's reader thread (no thread
        waits; every transport: the driver's callback exchanges do not depend on it)."""

        def finished(values: list[Any] | None, error: GripperError | None) -> None:
            if values is None:
                done(None, error)
                return
            try:
                st = _state_of(values)
            except Exception as exc:  # noqa: BLE001 - handed to the awaiting caller, never lost on the reader
                done(None, exc)
                return
            done(st, None)

        reads = self._client.start_queries(_STATE_READS, finished)
        # Each query times out in the driver as the threaded call's does (its reader keeps the time): no
        # caller timer.
        return StartedRead(cancel=reads.cancel, timeout=None)

    def abandon(self, thread_ident: int) -> None:
        self._client.abandon(thread_ident)

    def resume(self, thread_ident: int) -> None:
        self._client.resume(thread_ident)

    def info(self) -> DeviceInfo:
        si = self.system_info
        return DeviceInfo(
            family="wsg",
            vendor=self.profile.vendor,
            model=self.profile.model,
            serial=str(si.serial),
            firmware=str(si.firmware),
            hardware=str(si.hw_revision),
            limits=self.limits,
            url=self.url,
            profile=self.profile.name,
            extra={"device_type": int(si.device_type), "warnings": list(self.warnings)},
        )

    def close(self) -> None:
        self._client.close()


class _Feature:
    """An optional feature over the device's client of the moment (a reconnection swaps the client)."""

    def __init__(self, device: WsgDevice) -> None:
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

    def __init__(self, device: WsgDevice) -> None:
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

    def __init__(self, device: WsgDevice, connect: Callable[[], WsgClient]) -> None:
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


def _narrow(limits: Limits, device: SystemLimits, profile: str) -> tuple[Limits, list[str]]:
    """The profile's limits within the device's own 53h limits (mm, mm/s, N in; SI out), and warnings.

    A device value that is not finite or not positive cannot be a limit (an emulator that sends big-endian
    integers there gave "speed 50 mm/s is outside 5..-2.8e-17 mm/s" on every move): it is ignored with a
    warning and the profile's value is kept. So is a pair whose narrowed range would be empty (min > max).
    """
    warnings: list[str] = []

    def usable(name: str, value: float, unit: str) -> float | None:
        if math.isfinite(value) and value > 0:
            return value
        warnings.append(
            f"device reports {name} {value!r} {unit} (53h), not a positive finite number: "
            f"ignored, the {profile!r} profile's limit is used"
        )
        return None

    stroke = usable("stroke", float(device.stroke), "mm")
    min_speed = usable("min_speed", float(device.min_speed), "mm/s")
    max_speed = usable("max_speed", float(device.max_speed), "mm/s")
    min_force = usable("min_force", float(device.min_force), "N")
    nominal_force = usable("nominal_force", float(device.nominal_force), "N")
    update: dict[str, float] = {}
    if stroke is not None:
        update["max_width"] = min(limits.max_width, stroke / 1000)
    for lo_key, hi_key, lo, hi, scale, unit in (
        ("min_speed", "max_speed", min_speed, max_speed, 1000.0, "mm/s"),
        ("min_force", "max_force", min_force, nominal_force, 1.0, "N"),
    ):
        lo_v = getattr(limits, lo_key) if lo is None else max(getattr(limits, lo_key), lo / scale)
        hi_v = getattr(limits, hi_key) if hi is None else min(getattr(limits, hi_key), hi / scale)
        if lo_v > hi_v:
            warnings.append(
                f"device limits leave no {lo_key.split('_')[1]} range with the profile's "
                f"({lo!r}..{hi!r} {unit}, 53h): ignored, the {profile!r} profile's limits "
                "are used"
            )
            continue
        update[lo_key], update[hi_key] = lo_v, hi_v
    if "max_width" in update and update["max_width"] < limits.min_width:
        warnings.append(f"device stroke {stroke!r} mm (53h) is below the profile's minimum width: ignored")
        del update["max_width"]
    return limits.model_copy(update=update), warnings


class WsgBackend:
    family = "wsg"
    profile_model = WsgProfile
    # What a bare transport's URL would be for a WSG (the "did you mean" of a mistyped target), ranked.
    bare_forms = {
        "tcp": (10, "wsg+tcp://{rest}"),
        "udp": (10, "wsg+udp://{rest}"),
        "serial": (10, "wsg+serial://{rest}"),
        "can": (20, "wsg+can://{rest}"),
    }
    reports_stroke = True  # 53h: selftest compares it with the profile

    @property
    def cli_sim(self) -> Any:
        """``grippers sim``'s options and server start for this family (grippers/cli/sim.py asks for it)."""
        from . import wsg_cli

        return wsg_cli

    @property
    def device_settings(self) -> Any:
        """``grippers settings`` and ``selftest``: what this family stores besides its motion."""
        from .wsg_settings import WsgDeviceSettings

        return WsgDeviceSettings()

    def selftest_checks(self, gripper: Any, add: Callable[..., None]) -> None:
        """``grippers selftest``'s lines of this family (``add(name, measured, expected, verdict, note)``)."""
        from .wsg_settings import selftest_checks

        selftest_checks(gripper, add)

    def dissector(self) -> Any:
        """``grippers monitor``: WSG packets from bytes (captures, the TCP proxy) or CAN frames."""
        from grippers.drivers.wsg.dissect import PROTOCOL, WsgCanDissector, WsgStream

        from . import Dissector

        return Dissector(
            PROTOCOL,
            stream=WsgStream,
            can=lambda o: WsgCanDissector(o.get("wsg_id", 0x000), bool(o.get("only"))),
            tcp_port=WsgTransport().tcp_port,
            bytes_default=True,
        )

    factory_address = "tcp://192.168.1.20:1000"  # set-up default (docs/protocols.md §1): the machine scan

    def probe_candidates(self, transport: str, where: ConnectionURL, options: dict[str, Any]) -> list[Any]:
        """``grippers probe`` on a bare transport: the WSG's ports, its serial speed, its CAN id pairs."""
        from .wsg_cli import probe_candidates

        return probe_candidates(transport, where, options)

    def raw_probe(self, transport: str) -> Any:
        from .wsg_cli import raw_probe

        return raw_probe(transport)

    def open(self, url: ConnectionURL, profile: ProfileBase | None, settings: Settings) -> DeviceGripper:
        t = profile.transport if isinstance(profile, WsgProfile) else WsgTransport()
        timeout = settings.positive("timeout", t.timeout_s)
        common = {
            "device": url.url,
            "timeout": timeout,
            "verify_checksum": settings.bool("verify_checksum", t.verify_checksum),
        }
        # Every setting is taken once, here; reconnection reuses this connector, so it dials exactly what was
        # opened (a profile's tcp_port, the URL's local_port), never a re-parse of the URL (issue 20 §1).
        connect: Callable[[], WsgClient]
        if url.transport in ("tcp", "udp") and not url.host:
            raise URLError(f"{url.url}: a {url.transport} URL needs a host")
        if url.transport == "serial" and not url.serial_port:
            raise URLError(f"{url.url}: a serial URL needs a port")
        host, serial_port = url.host or "", url.serial_port or ""
        if url.transport == "tcp":
            port = url.port or t.tcp_port
            connect = lambda: WsgClient.tcp(host, port, **common)  # noqa: E731
        elif url.transport == "udp":
            local_port = settings.int("local_port", t.udp_local_port)
            port = url.port or t.udp_port
            connect = lambda: WsgClient.udp(host, port, local_port=local_port, **common)  # noqa: E731
        elif url.transport == "serial":
            framing = {
                "baudrate": settings.int("baudrate", t.baudrate),
                "bytesize": settings.int("bytesize", t.bytesize),
                "parity": settings.str("parity", t.parity),
                "stopbits": settings.float("stopbits", t.stopbits),
            }
            connect = lambda: WsgClient.serial(serial_port, **framing, **common)  # noqa: E731
        else:
            can = {
                "interface": settings.str("interface", url.interface),
                "channel": settings.str("channel", url.channel),
                "bitrate": settings.int("bitrate", t.can_bitrate),
                "send_id": settings.int("send_id", t.can_send_id),
                "recv_id": settings.int("recv_id", t.can_recv_id),
                "port": settings.int("port", None),  # udp_multicast's port (drivers/urls.py bus_options)
            }
            connect = lambda: WsgClient.can(**can, **common)  # noqa: E731
        settings.check()  # a misspelt setting is refused here, before anything is opened or sent
        client = connect()
        try:
            info = client.system_info()
            if not isinstance(profile, WsgProfile):
                profile = wsg_profile_for_device_type(int(info.device_type)) or load_profile(FALLBACK_PROFILE)
            device_limits = client.system_limits()
            assert isinstance(profile, WsgProfile)
            device = WsgDevice(
                client,
                profile,
                url.url,
                system_info=info,
                device_limits=device_limits,
                connect=connect,
            )
            gripper = DeviceGripper(device, profile, url.url, timeout=timeout)
            gripper.limits = device.limits  # narrowed by the device's 53h answer
            return gripper
        except BaseException:
            client.close()
            raise

    def simulator(self, profile: ProfileBase, settings: Settings, listen: str | None = None) -> Any:
        """A WSG simulator for ``profile`` serving on ``listen`` (default: loopback TCP, a free port)."""
        from grippers.drivers.wsg.sim import WsgModel, serve

        assert isinstance(profile, WsgProfile)
        m, sim = profile.mechanics, profile.simulator
        model = WsgModel(
            device_type=profile.wsg.device_type,
            stroke_mm=m.stroke_mm,
            min_speed=m.min_speed_mm_s,
            max_speed=m.max_speed_mm_s,
            min_accel=m.min_accel_mm_s2 or 100.0,
            max_accel=m.max_accel_mm_s2 or 5000.0,
            min_force=m.min_force_n,
            max_force=m.max_force_n,
            firmware=settings.str("firmware", sim.firmware),
            serial=settings.int("serial", sim.serial),
            part_width_mm=settings.float("part_width_mm", sim.part_width_mm),
            clamping_travel_mm=settings.float("clamping_travel_mm", profile.wsg.clamping_travel_mm),
            force_fingers=settings.bool("force_fingers", sim.force_fingers),
        )
        transport = settings.str("transport", "tcp")
        if listen is None:
            listen = {
                "tcp": "tcp://127.0.0.1:0",
                "udp": "udp://127.0.0.1:0",
                "pty": "pty",
                "serial": "pty",
                "can": f"can://virtual/grippers-sim-{uuid.uuid4().hex[:12]}",
            }.get(transport)
            if listen is None:
                raise URLError(f"{settings.url}: transport must be tcp, udp, pty or can, not {transport!r}")
        return serve(model, listen, time_scale=settings.positive("time_scale", sim.time_scale))

    def simulate(self, profile: ProfileBase, settings: Settings) -> Any:
        return self.simulator(profile, settings)
