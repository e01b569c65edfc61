"""The WSG backend: :class:`WsgDevice`, a :class:`grippers.device.Device` over a WSG client, in SI units.

:meth:`WsgBackend.open` returns the :class:`~grippers.gripper.Gripper` holding it.

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
from functools import cached_property
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
from ..errors import MotionBlocked, NotReferenced, URLError
from ..gripper import Gripper
from ..profiles import Limits, ProfileBase, load_profile
from ..settings import Settings
from ..states import Capability, DeviceInfo, GraspResult, GraspState, GripperState, MotionResult
from ..urls import ConnectionURL
from .command_hooks import CommandHooks
from .wsg_features import WsgDeviceTag, WsgReconnection, WsgServo, WsgSoftLimits, WsgTemperature
from .wsg_profile import WsgProfile, WsgTransport, wsg_profile_for_device_type

if TYPE_CHECKING:
    pass

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
    def _typed(self, command: str, target: float | None = None, sent: float | None = None) -> Iterator[None]:
        """The device's refusals that every family reports alike (issue 31 §1), as their typed errors:
        E_NOT_INITIALIZED (manual 4.0.x §3.2: a motion before homing) is :class:`NotReferenced`, and
        E_AXIS_BLOCKED on a pre-position or release (§3.2.2: the fingers met an obstacle; with stop-on-block
        they stop there) is :class:`MotionBlocked` with the width where they stopped. ``target`` None: a
        grasp, where meeting something is the point (its E_AXIS_BLOCKED, if any, passes unchanged).
        E_RANGE_ERROR for a width ``sent`` (m) outside the soft limits stored in the device names those
        limits and how to clear them (issue 39 §2), not only the device's status name."""
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
            said = self._outside_soft_limits(target if sent is None else sent, exc)
            if said is not None:
                raise CommandFailed(said, **kw) from exc
            if exc.status == Status.E_AXIS_BLOCKED and target is not None:
                width = self._client.width() / 1000
                if abs(width - target) <= MotionBlocked.MARGIN:
                    return  # stopped on the part where it was sent: the target was reached
                raise MotionBlocked(width=width, target=target, **kw) from exc
            raise

    def _outside_soft_limits(self, width: float | None, exc: CommandFailed) -> str | None:
        """What to tell a user whose width the device refused for its soft limits (WSG manual 4.0.x
        §3.3.5-§3.3.7: 34h-36h), or None when the refusal has another cause."""
        if exc.status != Status.E_RANGE_ERROR or width is None:
            return None
        try:
            limits = self._client.soft_limits()
        except GripperError:  # none set (E_NOT_AVAILABLE), or no answer: the device's own words stand
            return None
        mm = width * 1000
        if limits.minus - 1e-6 <= mm <= limits.plus + 1e-6:
            return None
        return (
            f"width {mm:g} mm is outside the soft limits {limits.minus:g}..{limits.plus:g} mm stored in the "
            f"device ({exc.status_name}): stay within them, or clear them (clear_soft_limits(); "
            "grippers settings URL --clear-soft-limits)"
        )

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
            with self._typed("grasp", sent=width):
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

    @cached_property
    def commands(self) -> CommandHooks:
        """What the commands ask of the family (wsg_cli.py, imported when a command asks)."""
        from .wsg_cli import WsgCommands

        return WsgCommands()

    def open(self, url: ConnectionURL, profile: ProfileBase | None, settings: Settings) -> Gripper:
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
            gripper = Gripper(device, profile, url.url, timeout=timeout)
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
