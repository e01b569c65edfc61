"""The SCHUNK backend: EGU, EGK and EZU over the web API (``schunk+http://HOST[:PORT]``) and Modbus RTU
(``schunk+serial:///dev/ttyUSB0[?slave=12]``), on :class:`grippers.drivers.schunk.client.SchunkClient`.

The semantics on the common interface (docs/getting-started-schunk.md says the same to users):

- a command is done when "command received" (bit 5) has toggled and the outcome bits say so, never on bits
  left from the previous command (:class:`~grippers.drivers.schunk.protocol.CommandTracker`);
- ``home()`` makes the unit ready for operation: on a unit in error (a unit powers up in 0xD9, fast stop) it
  acknowledges, as ``acknowledge()`` does; on a ready unit it sends nothing. ``open()`` never clears an error;
- ``move()`` is "move to absolute position" (bit 13) at the speed given; ``grasp()`` is "grip" (bit 12) at the
  speed given (at most the unit's maximum gripping speed, 0x0650) with the force as a percentage of the
  maximum gripping force (0x0660), rounded to the unit's 1 %; gripped or no workpiece from bits 12 and 11;
- ``release()`` is "release workpiece" (bit 11: opens by the release delta, 0x0540) when a part is held, then
  a move to the width asked (fully open by default);
- ``stop()`` is bit 1; ``fast_stop()`` clears bit 0 (the unit then reports error 0xD9 and refuses motion
  until ``acknowledge()``); a device error (bit 7, its code in the diagnostics) is ``CommandFailed`` with the
  code and SCHUNK's name for it.
"""

from __future__ import annotations

import threading
import time
from collections.abc import Callable
from functools import cached_property
from typing import TYPE_CHECKING, Any

from grippers.drivers.errors import CommandFailed, GripperError, GripperTimeout
from grippers.drivers.schunk.client import ParameterLink, SchunkClient
from grippers.drivers.schunk.protocol import (
    ERR_FAST_STOP,
    TOGGLE_TIMEOUT_S,
    CommandTracker,
    Control,
    ControlWord,
    Outcome,
    ProcessInput,
    Status,
    error_name,
    profile_name,
)

from ..device import Device
from ..errors import FastStopActive, MotionBlocked, URLError
from ..gripper import Gripper
from ..kit.motion import MotionEpochs, poll_until
from ..profiles import ProfileBase
from ..states import Capability, DeviceInfo, GraspResult, GraspState, GripperState, MotionResult
from .command_hooks import CommandHooks
from .schunk_profile import FALLBACK_PROFILE, SchunkProfile

if TYPE_CHECKING:
    from ..profile_model import Limits
    from ..servo import ServoTarget
    from ..settings import Settings
    from ..urls import ConnectionURL

GO = Control.FAST_STOP_OFF  # every command word carries bit 0 set (active-low fast stop)


def device_error(reading: ProcessInput, *, device: str, command: str) -> GripperError:
    """The unit's error (bit 7) as a typed error: 0xD9 is its fast stop."""
    code = reading.error
    name = error_name(code)
    if code == ERR_FAST_STOP:
        return FastStopActive(
            f"the unit is in fast stop ({name}, 0x{code:02X}): call acknowledge()",
            device=device,
            command=command,
        )
    return CommandFailed(
        f"the unit reports {name} (0x{code:02X}); acknowledge() clears it",
        status=code,
        status_name=name,
        device=device,
        command=command,
    )


def firmware_version(text: str) -> str | None:
    """The unit's ``sw_version_txt`` (``5.3.0.90971``: version and build) as the library writes versions,
    ``5.3.0-90971``; a text of another shape is kept as it is."""
    parts = text.split(".")
    if len(parts) == 4 and all(p.isdigit() for p in parts):
        return f"{'.'.join(parts[:3])}-{parts[3]}"
    return text or None


class SchunkDevice(Device):
    """One unit in SI units (positions: the distance between the jaws). It keeps its fast stop (0xD9) until
    acknowledged, but home() acknowledges the power-up fast stop, so the gripper's latch is the one for
    this client's own ``fast_stop()`` (``reports_fast_stop`` False)."""

    capabilities = frozenset({Capability.FORCE_CONTROL, Capability.TEMPERATURE, Capability.SOFT_LIMITS})
    reports_fast_stop = False

    def __init__(
        self,
        client: SchunkClient,
        profile: SchunkProfile,
        url: str,
        *,
        timeout: float,
        connect: Callable[[], SchunkClient] | None = None,
        gpe: bool = False,
        toggle_timeout: float = TOGGLE_TIMEOUT_S,
    ) -> None:
        self.client, self.profile, self.url, self.timeout = client, profile, url, timeout
        self.connect, self.gpe, self.toggle_timeout = connect, gpe, toggle_timeout
        self.epochs = MotionEpochs()
        self.commanding = threading.Lock()  # one command sequence at a time (_send); fast_stop() never waits
        self.tracker: CommandTracker | None = None  # the last motion command, while its answer is pending
        self.reconnection = SchunkReconnection(self) if connect is not None else None
        self.temperature = SchunkTemperature(self)
        from .schunk_settings import SchunkSoftLimits

        self.soft_limits = SchunkSoftLimits(self)
        self.servo = SchunkServo(self)

    @property
    def driver(self) -> SchunkClient:
        return self.client

    # -- limits from the unit's own parameters -----------------------------------------------------------

    def narrow_limits(self, limits: Limits) -> Limits:
        """The unit's parameters (position range, speeds, gripping forces), narrowed by the profile's safety
        section; the profile's mechanics only where the unit does not say."""
        p, s = self.client.parameters, self.profile.safety

        def got(name: str, default: float, scale: float) -> float:
            value = p.get(name)
            return float(value) * scale if isinstance(value, float) and value >= 0 else default

        lo, hi = got("min_pos", limits.min_width, 1e-3), got("max_pos", limits.max_width, 1e-3)
        max_speed = got("max_vel", limits.max_speed, 1e-3)
        max_force = got("max_grp_force", limits.max_force, 1.0)
        if s.max_speed_mm_s is not None:
            max_speed = min(max_speed, s.max_speed_mm_s / 1000)
        if s.max_force_n is not None:
            max_force = min(max_force, s.max_force_n)
        return limits.model_copy(
            update={
                "min_width": max(lo, (s.min_width_mm or 0.0) / 1000),
                "max_width": hi if s.max_width_mm is None else min(hi, s.max_width_mm / 1000),
                "min_speed": min(got("min_vel", limits.min_speed, 1e-3), max_speed),
                "max_speed": max_speed,
                "min_force": min(got("min_grp_force", limits.min_force, 1.0), max_force),
                "max_force": max_force,
            }
        )

    # -- commands ----------------------------------------------------------------------------------------

    def _read(self, command: str) -> ProcessInput:
        return self.client.read_input(command)

    def _send(self, word: ControlWord, kind: str, command: str) -> CommandTracker:
        """Send a command and wait (bounded) until the unit has toggled "command received".

        One command's three steps at a time (``commanding``): a stop from another thread between a move's
        status read and its command word would toggle bit 5 for the move's tracker, and the move's word,
        written after the stop, would start the jaws again."""
        with self.commanding:
            tracker = self.client.start(word, kind, command)
            deadline = time.monotonic() + max(self.toggle_timeout, 0.0)
            while True:
                reading = self._read(command)
                if tracker.received(reading):
                    return tracker
                if time.monotonic() > deadline:
                    raise GripperTimeout(
                        f"the unit did not toggle 'command received' within {self.toggle_timeout:g} s",
                        device=self.name,
                        command=command,
                    )
                time.sleep(0.002)

    def _wait(
        self, tracker: CommandTracker, command: str, timeout: float, motion: int | None
    ) -> ProcessInput:
        def fault(reading: ProcessInput) -> GripperError | None:
            outcome = tracker.outcome(reading)
            if outcome is Outcome.ERROR:
                return device_error(reading, device=self.name, command=command)
            if outcome is Outcome.NOT_FEASIBLE:
                return CommandFailed(
                    "the unit reports 'command not feasible' (bit 3)", device=self.name, command=command
                )
            return None

        return poll_until(
            lambda: self._read(command),
            lambda reading: tracker.outcome(reading) is not Outcome.PENDING,
            context=self.context,
            command=command,
            timeout=timeout,
            epochs=self.epochs if motion is not None else None,
            motion=motion or 0,
            fault=fault,
        )

    def _motion(
        self, word: ControlWord, kind: str, command: str, timeout: float
    ) -> tuple[ProcessInput, Outcome]:
        motion = self.epochs.begin(f"superseded by a newer motion before it ended ({command})")
        tracker = self._send(word, kind, command)
        self.tracker = tracker
        try:
            reading = self._wait(tracker, command, timeout, motion)
            return reading, tracker.outcome(reading)
        finally:
            if self.tracker is tracker:
                self.tracker = None

    def _gpe(self) -> Control:
        return Control.GPE if self.gpe and self.client.gpe_available else Control(0)

    def home(self, timeout: float) -> None:
        reading = self._read("home")
        if reading.has(Status.READY) and not reading.has(Status.ERROR):
            return
        self._acknowledge("home", timeout)

    def move(self, width: float, speed: float, timeout: float) -> MotionResult:
        word = ControlWord(GO | Control.MOVE_ABSOLUTE | self._gpe(), round(width * 1e6), round(speed * 1e6))
        reading, _ = self._motion(word, "move", "move", timeout)
        return self._arrived(reading, width, "move")

    def _arrived(self, reading: ProcessInput, width: float, command: str) -> MotionResult:
        at = reading.position_um / 1e6
        if abs(at - width) > MotionBlocked.MARGIN:
            raise MotionBlocked(width=at, target=width, device=self.name, command=command)
        return MotionResult(at, GraspState.IDLE)

    def grasp(self, width: float, speed: float, force: float, timeout: float) -> GraspResult:
        percent = self.force_percent(force)
        grip_speed = min(speed, float(self.client.parameters.get("max_grp_vel", 0.0)) / 1000 or speed)
        word = ControlWord(GO | Control.GRIP | self._gpe(), 0, round(grip_speed * 1e6), percent)
        reading, outcome = self._motion(word, "grip", "grasp", timeout)
        at = reading.position_um / 1e6
        if outcome is Outcome.GRIPPED:
            return GraspResult(True, at, percent / 100 * self._max_force(force), GraspState.HOLDING)
        reason = "wrong workpiece (bit 17)" if outcome is Outcome.WRONG_WORKPIECE else "no workpiece detected"
        return GraspResult(False, at, None, GraspState.NO_PART, reason=reason)

    def _max_force(self, fallback: float) -> float:
        value = self.client.parameters.get("max_grp_force")
        return float(value) if isinstance(value, float) and value > 0 else fallback

    def force_percent(self, force: float) -> int:
        """The force as the unit takes it: % of its maximum gripping force, rounded to whole percent."""
        maximum = self._max_force(self.profile.mechanics.max_force_n)
        return max(1, min(100, round(force / maximum * 100)))

    def release(self, width: float, speed: float, timeout: float) -> MotionResult:
        reading = self._read("release")
        if reading.has(Status.GRIPPED):
            word = ControlWord(GO | Control.RELEASE | self._gpe())
            reading, _ = self._motion(word, "release", "release", timeout)
        if abs(reading.position_um / 1e6 - width) <= MotionBlocked.MARGIN:
            return MotionResult(reading.position_um / 1e6, GraspState.IDLE)
        word = ControlWord(GO | Control.MOVE_ABSOLUTE | self._gpe(), round(width * 1e6), round(speed * 1e6))
        return self._arrived(self._motion(word, "move", "release", timeout)[0], width, "release")

    def stop(self) -> None:
        self.epochs.begin("aborted by stop()")
        tracker = self._send(ControlWord(GO | Control.STOP | self._gpe()), "stop", "stop")
        self.tracker = None
        try:
            self._wait(tracker, "stop", self.timeout, None)
        except CommandFailed:
            pass  # a unit in error ignores the stop: nothing moves

    def fast_stop(self) -> None:
        """Bit 0 low, the unit's fast stop: sent as the only write (no empty word first), at once."""
        self.epochs.begin("aborted by fast_stop()")
        self.tracker = None
        self.client.send(ControlWord(Control(0)), "fast_stop")

    def acknowledge(self) -> None:
        self._acknowledge("acknowledge", self.timeout)

    def _acknowledge(self, command: str, timeout: float) -> None:
        tracker = self._send(ControlWord(GO | Control.ACKNOWLEDGE), "acknowledge", command)
        reading = self._wait(tracker, command, timeout, None)
        if not reading.has(Status.READY):
            raise device_error(reading, device=self.name, command=command)

    # -- state -------------------------------------------------------------------------------------------

    def read_state(self) -> GripperState:
        reading = self._read("state")
        tracker = self.tracker
        moving = tracker is not None and tracker.outcome(reading) is Outcome.PENDING
        s = reading.status
        if moving:
            grasp = (
                GraspState.GRASPING
                if tracker is not None and tracker.kind == "grip"
                else GraspState.POSITIONING
            )
        elif s & Status.GRIPPED:
            grasp = GraspState.HOLDING
        elif s & (Status.NO_WORKPIECE | Status.WRONG_WORKPIECE):
            grasp = GraspState.NO_PART
        elif s & Status.ERROR:
            grasp = GraspState.ERROR
        else:
            grasp = GraspState.IDLE
        faults: tuple[str, ...] = ()
        if s & Status.ERROR:
            faults = (error_name(reading.error),)
        elif not s & Status.READY:
            faults = ("not_ready",)
        return GripperState(
            width=reading.position_um / 1e6,
            speed=None,
            force=None,
            current=None,
            grasp=grasp,
            moving=moving,
            # The units have no reference run (no control bit for one: SCHUNK's driver.py) and report their
            # position from power-up; readiness is a fault (ERR_FAST_STOP, not_ready) home() acknowledges.
            referenced=True,
            faults=faults,
            timestamp=time.time(),
        )

    def info(self) -> DeviceInfo:
        p, prof = self.client.parameters, self.profile
        return DeviceInfo(
            family="schunk",
            vendor=prof.vendor,
            model=prof.model,
            serial=str(p.get("serial_no_txt") or "") or None,
            firmware=firmware_version(str(p.get("sw_version_txt") or "")),
            hardware=None,
            limits=self.narrow_limits(prof.limits()),
            url=self.url,
            profile=prof.name,
            extra={
                "module_type": self.client.module_type,
                "firmware_text": p.get("sw_version_txt"),
                "fieldbus": self.client.fieldbus.short,
                "gpe_available": self.client.gpe_available,
                "gpe": self.gpe,
                "release_delta_mm": p.get("wp_release_delta"),
                "max_grip_speed_mm_s": p.get("max_grp_vel"),
                "force_resolution": "1 % of the maximum gripping force",
            },
        )

    def close(self) -> None:
        self.client.close()


class SchunkServo:
    """``servo()``: each new target is the empty word and a "move to absolute position" word (two writes,
    no status read and no wait): the unit takes a command on a new command word, as SCHUNK's driver's empty
    word before every command shows. The same target again sends nothing."""

    def __init__(self, device: SchunkDevice) -> None:
        self._device = device
        self._last: ControlWord | None = None

    def begin(self) -> None:
        reading = self._device._read("servo")
        if reading.has(Status.ERROR):
            raise device_error(reading, device=self._device.name, command="servo")
        self._last = None

    def send(self, target: ServoTarget) -> bool | None:
        d = self._device
        word = ControlWord(
            GO | Control.MOVE_ABSOLUTE | d._gpe(), round(target.width * 1e6), round(target.speed * 1e6)
        )
        if word == self._last:
            return False
        d.epochs.begin("superseded by a servo target")
        with d.commanding:
            d.client.send(ControlWord(GO), "servo")
            d.client.send(word, "servo")
        self._last = word
        return True

    def end(self) -> None:
        self._last = None


class SchunkTemperature:
    """The unit's logic temperature (0x0840, meas_lgc_temp, °C)."""

    def __init__(self, device: SchunkDevice) -> None:
        self.device = device

    def read(self) -> float:
        return float(self.device.client.read_parameter("meas_lgc_temp", "temperature"))


class SchunkReconnection:
    """``reconnect=true``: a fresh link on the same URL once the unit answers there, the same unit (its serial
    number), its parameters read again."""

    def __init__(self, device: SchunkDevice) -> None:
        self.device = device

    def alive(self) -> bool:
        return self.device.client.alive

    def identity(self) -> dict[str, str]:
        p = self.device.client.parameters
        return {"module_type": self.device.client.module_type, "serial": str(p.get("serial_no_txt", ""))}

    def reconnect(self) -> None:
        assert self.device.connect is not None
        # The old link goes first: a serial port is opened exclusively (drivers/serial_ports.py), so the
        # fresh link could not have it while the dead one holds it. Closing twice is harmless.
        self.device.client.close()
        fresh = self.device.connect()
        try:
            fresh.connect("reconnect")
            new = {"module_type": fresh.module_type, "serial": str(fresh.parameters.get("serial_no_txt", ""))}
            self.device.context.check_same_device(new)
        except BaseException:
            fresh.close()
            raise
        old, self.device.client = self.device.client, fresh
        old.close()


def link_for(url: ConnectionURL, profile: SchunkProfile, settings: Settings) -> Callable[[], ParameterLink]:
    """How to open the unit's link (kept for reconnection): the web API, or Modbus RTU on a serial line."""
    s = profile.schunk
    timeout = settings.positive("timeout", s.timeout_s)
    if url.transport == "serial":
        from grippers.drivers.schunk.rtu import RtuLink

        port, slave = url.serial_port, settings.int("slave", s.device_id)
        baudrate = settings.int("baudrate", s.baudrate)
        if not port:
            raise URLError(f"{url.url}: a serial URL needs a port")
        if not 1 <= slave <= 247:
            raise URLError(f"{url.url}: slave must be 1..247, not {slave}")
        return lambda: RtuLink.serial(port, slave=slave, baudrate=baudrate, device=url.url, timeout=timeout)
    if url.transport == "tcp":
        from grippers.drivers.schunk.webapi import WebLink

        protocol = settings.str("protocol", "http")
        if protocol != "http" or not url.host:
            raise URLError(f"{url.url}: a SCHUNK unit's web API is schunk+http://HOST[:PORT]")
        host, port_no = url.host, url.port or s.http_port
        return lambda: WebLink(host, port_no, device=url.url, timeout=timeout)
    raise URLError(
        f"{url.url}: SCHUNK units speak http (schunk+http://HOST) or Modbus RTU (schunk+serial://PORT)"
    )


class SchunkBackend:
    family = "schunk"
    profile_model = SchunkProfile
    url_protocols = {"http": "tcp"}  # schunk+http://HOST[:80]: the web API (grippers/urls.py)

    @cached_property
    def commands(self) -> CommandHooks:
        """What the commands ask of the family (schunk_cli.py, imported when a command asks)."""
        from .schunk_cli import SchunkCommands

        return SchunkCommands()

    def open(self, url: ConnectionURL, profile: ProfileBase | None, settings: Settings) -> Gripper:
        from ..profiles import load_profile

        named = profile
        if named is not None and not isinstance(named, SchunkProfile):
            raise URLError(f"{url.url}: profile {named.name!r} is not a SCHUNK profile")
        base = named if isinstance(named, SchunkProfile) else load_profile(FALLBACK_PROFILE)
        assert isinstance(base, SchunkProfile)
        timeout = settings.positive("timeout", base.schunk.timeout_s)
        gpe = settings.bool("gpe", base.schunk.gpe)
        toggle = settings.positive("toggle_timeout", max(TOGGLE_TIMEOUT_S, timeout))
        make_link = link_for(url, base, settings)

        def connect() -> SchunkClient:
            link = make_link()
            if hasattr(link, "probe"):
                try:
                    link.probe()
                except BaseException:
                    link.close()
                    raise
            return SchunkClient(link)

        client = connect()
        try:
            client.connect("open")
            chosen = base if named is not None else self._profile_of(client, base)
            device = SchunkDevice(
                client, chosen, url.url, timeout=timeout, connect=connect, gpe=gpe, toggle_timeout=toggle
            )
            return Gripper(device, chosen, url.url, timeout=timeout)
        except BaseException:
            client.close()
            raise

    @staticmethod
    def _profile_of(client: SchunkClient, fallback: SchunkProfile) -> SchunkProfile:
        """The profile of the size the unit reports (0x0500), or the fallback: the limits come from the
        unit's parameters either way."""
        from ..errors import ProfileError
        from ..profiles import load_profile

        name = profile_name(client.module_type)
        try:
            found = load_profile(name) if name else fallback
        except ProfileError:
            return fallback
        return found if isinstance(found, SchunkProfile) else fallback

    def simulator(self, profile: ProfileBase, settings: Settings, listen: str | None = None) -> Any:
        """A simulated unit of ``profile`` serving its web API (default: loopback, a free port) or, with
        ``listen="pty"`` or ``?transport=pty``, Modbus RTU on a pseudo-terminal."""
        from grippers.drivers.schunk.protocol import Fieldbus
        from grippers.drivers.schunk.sim import ModuleSpec, SchunkModel, serve

        assert isinstance(profile, SchunkProfile)
        m, s, sim = profile.mechanics, profile.schunk, profile.simulator
        spec = ModuleSpec(
            module_type=s.module_type,
            module_name=profile.module_name,
            min_pos_mm=m.min_width_mm,
            max_pos_mm=m.max_width_mm,
            max_phys_stroke_mm=m.max_width_mm,
            min_vel_mm_s=m.min_speed_mm_s,
            max_vel_mm_s=m.max_speed_mm_s,
            max_grp_vel_mm_s=s.max_grip_speed_mm_s,
            min_grp_force_n=m.min_force_n,
            max_grp_force_n=m.max_force_n,
            release_delta_mm=s.release_delta_mm,
            serial=sim.serial,
            firmware=sim.firmware,
        )
        transport = settings.str("transport", "http")
        if listen is None:
            listen = {
                "http": "http://127.0.0.1:0",
                "tcp": "http://127.0.0.1:0",
                "pty": "pty",
                "serial": "pty",
            }.get(transport, "")
            if not listen:
                raise URLError(f"{settings.url}: transport must be http or pty, not {transport!r}")
        fieldbus_name = settings.str("fieldbus", "MB" if listen in ("pty", "serial") else sim.fieldbus)
        buses = {f.short: f for f in Fieldbus}
        if fieldbus_name not in buses:
            raise URLError(
                f"{settings.url}: fieldbus must be one of {', '.join(buses)}, not {fieldbus_name!r}"
            )
        part = settings.float("part_width_mm", sim.part_width_mm)
        model = SchunkModel(spec, buses[fieldbus_name], part_width_mm=part, position_mm=m.min_width_mm)
        slave = settings.int("slave", s.device_id)
        return serve(model, listen, time_scale=settings.positive("time_scale", sim.time_scale), slave=slave)
