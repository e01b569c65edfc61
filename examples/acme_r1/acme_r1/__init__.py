"""ACME R1 grippers for the ``grippers`` library: the worked plugin of docs/backends.md.

Three parts, as in every family: ``codec.py`` (the frames, sans-IO), ``sim.py`` (a simulator on the same
codec) and this module: the profile model (the ``[acme]`` section), :class:`AcmeLink` (register reads and
writes over the kit's TCP link), :class:`AcmeDevice` (the public device contract,
:class:`grippers.device.Device`, in SI units, with reconnection and servoing), :class:`AcmeCommands` (what the
commands ask beyond a gripper: settings, self-test lines, the probe's identity check, the monitor's dissector)
and :class:`AcmeBackend` (what the entry point names: open and the simulator). Only public names of
``grippers`` are used: the library's gripper holds the device and does the limits, the defaults, the motion
rule, the streams, servoing, the fast-stop latch and close; the command hooks' defaults derive the probe's
candidates from the profile's URL.
"""

from __future__ import annotations

import time
from collections.abc import Callable
from typing import TYPE_CHECKING, Literal

from pydantic import BaseModel, ConfigDict

from grippers import (
    Capability,
    CommandFailed,
    DeviceInfo,
    GraspResult,
    GraspState,
    Gripper,
    GripperError,
    GripperState,
    GripperTimeout,
    MotionBlocked,
    MotionResult,
    NotReferenced,
    URLError,
)
from grippers.device import Device
from grippers.kit import CommandHooks, Dissector, Identity, MotionEpochs, ServoTarget, TcpLink, poll_until
from grippers.profiles import ProfileBase, load_profile
from grippers.urls import parse_url

from .codec import MODEL_R1, Control, Decoder, Frame, Reg, Status

if TYPE_CHECKING:
    from argparse import Namespace

    from grippers.settings import Settings
    from grippers.urls import ConnectionURL

    from .sim import AcmeServer

Reading = tuple[Status, float]  # the status bits and the width (m)


class AcmeSection(BaseModel):
    model_config = ConfigDict(extra="forbid", frozen=True)
    tcp_port: int = 5500
    timeout_s: float = 0.5
    part_width_mm: float | None = None  # the simulator's part (sim://acme-r1?part_width_mm=30 overrides it)


class AcmeProfile(ProfileBase):
    family: Literal["acme"] = "acme"
    acme: AcmeSection = AcmeSection()


class AcmeLink:
    """Register reads and writes over the kit's TCP link (``grippers.kit.TcpLink``: one exchange at a time,
    each with a deadline, typed errors, ``alive`` False once the connection is lost)."""

    def __init__(self, host: str, port: int, *, timeout: float, device: str) -> None:
        self.link = TcpLink(host, port, device=device, timeout=timeout)
        self.decoder = Decoder()

    @property
    def alive(self) -> bool:
        return self.link.alive

    def exchange(self, request: Frame, command: str) -> Frame:
        try:
            reply = self.link.exchange(request.encode(), self.decoder.feed, command=command)[0]
        except GripperTimeout:
            self.decoder = Decoder()  # a late reply must not answer the next request
            raise
        if reply.op == "E":
            raise CommandFailed(
                f"device error {reply.addr}", status=reply.addr, device=self.link.device, command=command
            )
        return reply

    def read(self, reg: Reg, count: int, command: str) -> tuple[int, ...]:
        return self.exchange(Frame("R", reg, count=count), command).values

    def write(self, reg: Reg, *values: int, command: str) -> None:
        self.exchange(Frame("W", reg, values), command)

    def close(self) -> None:
        self.link.close()


def answering(connect: Callable[[], AcmeLink], command: str) -> AcmeLink:
    """A fresh link on which an ACME device answers a status read (or the link is closed and that raises)."""
    link = connect()
    try:
        link.read(Reg.STATUS, 1, command)
    except BaseException:
        link.close()
        raise
    return link


class AcmeDevice(Device):
    """One R1 in SI units. It takes a new target mid-motion (``moves_to_new_targets``: a newer motion needs no
    stop, only a new motion epoch), and has no fast-stop state (``reports_fast_stop`` False: the gripper
    latches it). Homing is required before motion (``Capability.HOMING``)."""

    capabilities = frozenset({Capability.HOMING})
    moves_to_new_targets = True
    reports_fast_stop = False

    def __init__(self, connect: Callable[[], AcmeLink], profile: AcmeProfile, url: str) -> None:
        self.connect, self.profile, self.url = connect, profile, url
        self.link = answering(connect, "open")
        self.limits = profile.limits()
        self.epochs = MotionEpochs()  # a newer motion or a stop ends the older waits
        self.reconnection = AcmeReconnection(self)
        self.servo = AcmeServo(self)

    @property
    def driver(self) -> AcmeLink:
        return self.link

    def status(self, command: str) -> Reading:
        status, position = self.link.read(Reg.STATUS, 2, command)
        return Status(status), position / 10_000  # 0.1 mm -> m

    def fault(self, reading: Reading, command: str) -> GripperError | None:
        """The fault bit as a typed error; the R1 keeps it until RESET, which goes out at once."""
        status, _ = reading
        if not status & Status.FAULT:
            return None
        self.link.write(Reg.CONTROL, Control.RESET, command=command)
        if not status & Status.HOMED:
            return NotReferenced(f"{command} before home()", device=self.name, command=command)
        return CommandFailed("the device reports a fault", device=self.name, command=command)

    def send(self, command: str, width: float, speed: float, force: float) -> int:
        """Write the target and GO (HOME for home) in a new motion epoch, whose number it returns."""
        motion = self.epochs.begin(f"superseded by a newer motion before it ended ({command})")
        self.link.write(Reg.TARGET, round(width * 10_000), round(speed * 1000), round(force), command=command)
        self.link.write(Reg.CONTROL, Control.HOME if command == "home" else Control.GO, command=command)
        return motion

    def go(self, command: str, width: float, speed: float, force: float, timeout: float) -> Reading:
        """Send the motion, then poll until the jaws rest (grippers.kit.motion)."""
        motion = self.send(command, width, speed, force)
        return poll_until(
            lambda: self.status(command),
            lambda reading: not reading[0] & Status.MOVING,
            context=self.context,
            command=command,
            timeout=timeout,
            epochs=self.epochs,
            motion=motion,
            fault=lambda reading: self.fault(reading, command),
        )

    def home(self, timeout: float) -> None:
        m = self.limits
        self.go("home", m.max_width, m.min_speed + 0.5 * (m.max_speed - m.min_speed), m.min_force, timeout)

    def move(self, width: float, speed: float, timeout: float) -> MotionResult:
        status, at = self.go("move", width, speed, self.limits.min_force, timeout)
        if status & Status.OBJECT and abs(at - width) > MotionBlocked.MARGIN:
            raise MotionBlocked(width=at, target=width, device=self.name, command="move")
        return MotionResult(at, GraspState.IDLE)

    def grasp(self, width: float, speed: float, force: float, timeout: float) -> GraspResult:
        status, at = self.go("grasp", self.limits.min_width, speed, force, timeout)  # close until a part
        if status & Status.OBJECT:
            return GraspResult(True, at, force, GraspState.HOLDING)
        return GraspResult(False, at, None, GraspState.NO_PART, reason="closed without meeting a part")

    def stop(self) -> None:
        self.epochs.begin("aborted by stop()")
        self.link.write(Reg.CONTROL, Control.STOP, command="stop")

    def fast_stop(self) -> None:  # no brake: a stop; the gripper refuses motion until acknowledge()
        self.epochs.begin("aborted by fast_stop()")
        self.link.write(Reg.CONTROL, Control.STOP, command="fast_stop")

    def supersede(self) -> None:  # the R1 takes a new target mid-motion: the older wait ends, no stop
        self.epochs.begin("superseded by a newer motion before it ended")

    def acknowledge(self) -> None:
        self.link.write(Reg.CONTROL, Control.RESET, command="acknowledge")

    def read_state(self) -> GripperState:
        status, at = self.status("state")
        moving = bool(status & Status.MOVING)
        held = GraspState.HOLDING if status & Status.OBJECT else GraspState.IDLE
        return GripperState(
            width=at,
            speed=None,
            force=None,
            current=None,
            grasp=GraspState.POSITIONING if moving else held,
            moving=moving,
            referenced=bool(status & Status.HOMED),
            faults=("fault",) if status & Status.FAULT else (),
            timestamp=time.time(),
        )

    def info(self) -> DeviceInfo:
        p = self.profile
        status, _ = self.status("info")
        return DeviceInfo(
            family="acme",
            vendor=p.vendor,
            model=p.model,
            serial=None,
            firmware=None,
            hardware=None,
            limits=self.limits,
            url=self.url,
            profile=p.name,
            extra={"status": "|".join(f.name or "" for f in Status if f in status) or "idle"},
        )

    def close(self) -> None:
        self.link.close()


class AcmeReconnection:
    """``reconnect=true``: a fresh link on the same URL once the device answers there again."""

    def __init__(self, device: AcmeDevice) -> None:
        self.device = device

    def alive(self) -> bool:
        return self.device.link.alive

    def identity(self) -> dict[str, str]:
        return {}  # the R1 reports no serial number: units cannot be told apart

    def reconnect(self) -> None:
        new = answering(self.device.connect, "reconnect")
        old, self.device.link = self.device.link, new
        old.close()


class AcmeServo:
    """``Gripper.servo()``: each target sent with GO at once; the R1 heads for the newest without a stop."""

    def __init__(self, device: AcmeDevice) -> None:
        self.device = device

    def begin(self) -> None:
        pass

    def send(self, target: ServoTarget) -> bool:
        force = self.device.limits.min_force if target.force is None else target.force
        self.device.send("servo", target.width, target.speed, force)
        return True

    def end(self) -> None:
        pass


class AcmeCommands(CommandHooks):
    """What the commands ask of the family beyond a gripper; the probe's candidates are the defaults', built
    from the profile's URL (``acme+tcp://HOST``)."""

    default_profile = "acme-r1"  # `grippers sim acme` without --model
    sim_help = "simulate an ACME R1 gripper on loopback TCP"
    sim_example = "grippers sim acme --listen tcp://127.0.0.1:5500 --part-width 30"
    settings_options = ("force_limit",)

    def dissector(self) -> Dissector:
        from .codec import AcmeDissector

        return Dissector("acme", stream=AcmeDissector, tcp_port=AcmeSection().tcp_port)

    def probe_identity(self, gripper: Gripper) -> Identity:
        (model,) = gripper.driver.read(Reg.MODEL, 1, "probe")
        return Identity(model == MODEL_R1, f"register MODEL holds {model:#06x}")

    def read_settings(self, gripper: Gripper) -> dict[str, float]:
        return {"force_limit_n": float(gripper.driver.read(Reg.FORCE_LIMIT, 1, "settings")[0])}

    def check_settings(self, gripper: Gripper, args: Namespace) -> None:
        if args.force_limit is not None:
            gripper.check(force=args.force_limit, command="force_limit")  # the profile's force range

    def change_settings(self, gripper: Gripper, args: Namespace, changed: list[str]) -> None:
        if args.force_limit is not None:
            gripper.driver.write(Reg.FORCE_LIMIT, round(args.force_limit), command="settings")
            changed.append("force_limit_n")

    def selftest_checks(self, gripper: Gripper, add: Callable[..., None]) -> None:
        limit = self.read_settings(gripper)["force_limit_n"]
        ok = limit >= gripper.limits.max_force
        add("force limit", f"{limit:g} N", f">= {gripper.limits.max_force:g} N", "PASS" if ok else "WARN")


class AcmeBackend:
    """What the ``grippers.backends`` entry point names: the family's name, its profile model, the command
    hooks, ``open`` and the simulator."""

    family = "acme"
    profile_model = AcmeProfile
    commands = AcmeCommands()

    def open(self, url: ConnectionURL, profile: ProfileBase | None, settings: Settings) -> Gripper:
        profile = profile or load_profile("acme-r1")
        if not isinstance(profile, AcmeProfile):
            raise URLError(f"{url.url}: profile {profile.name!r} is not an ACME profile")
        if url.transport != "tcp" or not url.host:
            raise URLError(f"{url.url}: an ACME gripper speaks TCP (acme+tcp://HOST[:PORT])")
        host, port = url.host, url.port or profile.acme.tcp_port
        timeout = settings.positive("timeout", profile.acme.timeout_s)
        settings.check()  # a misspelt ?timout= is a URLError now, before anything is opened
        device = AcmeDevice(lambda: AcmeLink(host, port, timeout=timeout, device=url.url), profile, url.url)
        return Gripper(device, profile, url.url, timeout=timeout)

    def simulator(self, profile: ProfileBase, settings: Settings, listen: str | None = None) -> AcmeServer:
        """A simulated R1 on loopback TCP (``listen``: tcp://HOST:PORT, default a free port); ``sim://``,
        ``grippers sim acme`` and the conformance suite start it."""
        from .sim import AcmeModel, AcmeServer  # imported when a simulator is started

        assert isinstance(profile, AcmeProfile)
        where = parse_url(listen or "tcp://127.0.0.1:0", bare_family="acme", listen=True)
        if where.transport != "tcp":
            raise URLError(f"{listen}: the ACME simulator listens on tcp://HOST:PORT")
        model = AcmeModel(
            profile.mechanics.stroke_mm, settings.float("part_width_mm", profile.acme.part_width_mm)
        )
        scale = settings.positive("time_scale", 1.0)
        return AcmeServer(model, where.host or "127.0.0.1", where.port or 0, time_scale=scale)
