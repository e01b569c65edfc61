"""ACME R1 grippers for the ``grippers`` library: the worked plugin of docs/backends.md.

Three parts, as in every family: ``codec.py`` (the frames, sans-IO), ``sim.py`` (a simulator on the same
codec) and this module: the profile model (the ``[acme]`` section), :class:`AcmeLink` (a socket and the
exchange), :class:`AcmeGripper` (the ``Gripper`` methods in device units) and :class:`AcmeBackend` (what the
entry point names: open, the simulator, the probe's candidates).
"""

from __future__ import annotations

import socket
import threading
import time
from collections.abc import Callable
from typing import TYPE_CHECKING, Any, Literal

from pydantic import BaseModel, ConfigDict

from grippers import CommandFailed, ConnectionLost, Gripper, GripperTimeout, MotionBlocked, NotReferenced
from grippers.backends import ProbeCandidate
from grippers.backends.motion_epochs import MotionEpochs
from grippers.errors import URLError
from grippers.gripper import DeviceInfo, GraspResult, GraspState, GripperState, MotionResult
from grippers.profiles import ProfileBase

from .codec import Control, Decoder, Frame, FrameError, Reg, Status

if TYPE_CHECKING:
    from grippers.settings import Settings
    from grippers.urls import ConnectionURL

    from .sim import AcmeServer

POLL_S = 0.005  # between status reads while a motion runs


class AcmeSection(BaseModel):
    model_config = ConfigDict(extra="forbid", frozen=True)
    tcp_port: int = 5500
    timeout_s: float = 0.5
    part_width_mm: float | None = None  # the simulator's part (sim://acme-r1?part_width_mm=30 overrides it)


class AcmeProfile(ProfileBase):
    family: Literal["acme"] = "acme"
    acme: AcmeSection = AcmeSection()


class AcmeLink:
    """One TCP connection: ``read``/``write`` registers, one exchange at a time, each with a deadline."""

    def __init__(self, host: str, port: int, *, timeout: float, device: str) -> None:
        self.device, self.timeout = device, timeout
        self._lock = threading.Lock()
        try:
            self._sock = socket.create_connection((host, port), timeout=timeout)
        except OSError as exc:
            raise ConnectionLost(f"cannot connect: {exc}", device=device, command="open") from exc
        self._decoder = Decoder()

    def _exchange(self, request: Frame, command: str) -> Frame:
        with self._lock:
            try:
                self._sock.sendall(request.encode())
                deadline = time.monotonic() + self.timeout
                while True:
                    self._sock.settimeout(max(deadline - time.monotonic(), 1e-3))
                    data = self._sock.recv(256)
                    if not data:
                        raise ConnectionLost(
                            "the device closed the link", device=self.device, command=command
                        )
                    frames = self._decoder.feed(data)
                    if frames:
                        reply = frames[0]
                        break
            except TimeoutError as exc:
                self._decoder = Decoder()  # a late reply must not answer the next request
                raise GripperTimeout(
                    f"no reply within {self.timeout:g} s", device=self.device, command=command
                ) from exc
            except FrameError as exc:
                raise CommandFailed(f"garbled reply: {exc}", device=self.device, command=command) from exc
            except OSError as exc:
                raise ConnectionLost(str(exc), device=self.device, command=command) from exc
        if reply.op == "E":
            raise CommandFailed(
                f"device error {reply.addr}", status=reply.addr, device=self.device, command=command
            )
        return reply

    def read(self, reg: Reg, count: int, command: str) -> tuple[int, ...]:
        return self._exchange(Frame("R", reg, count=count), command).values

    def write(self, reg: Reg, *values: int, command: str) -> None:
        self._exchange(Frame("W", reg, values), command)

    def close(self) -> None:
        self._sock.close()


class AcmeGripper(Gripper):
    def __init__(self, connect: Callable[[], AcmeLink], profile: AcmeProfile, url: str) -> None:
        link = connect()
        try:
            link.read(Reg.STATUS, 1, "open")  # an ACME device answers, or the open fails here
        except BaseException:
            link.close()
            raise
        super().__init__(profile, url, timeout=link.timeout)
        self._connect, self._link = connect, link
        self._epochs = MotionEpochs()  # a newer motion or a stop ends the older waits
        self._latched = False  # fast_stop(): the R1 has no fast-stop state of its own

    @property
    def driver(self) -> AcmeLink:
        return self._link

    def _status(self, command: str) -> tuple[Status, float]:
        status, position = self._link.read(Reg.STATUS, 2, command)
        return Status(status), position / 10_000  # 0.1 mm -> m

    def _go(
        self, command: str, width: float, speed: float, force: float, timeout: float
    ) -> tuple[Status, float]:
        """Write the target and GO, then poll until the jaws rest; never reported done when superseded."""
        motion = self._epochs.begin(f"superseded by a newer motion before it ended ({command})")
        self._link.write(
            Reg.TARGET, round(width * 10_000), round(speed * 1000), round(force), command=command
        )
        self._link.write(Reg.CONTROL, Control.GO if command != "home" else Control.HOME, command=command)
        deadline = time.monotonic() + timeout
        while True:
            self._epochs.check(motion, command=command, device=self.name)
            status, at = self._status(command)
            self._epochs.check(motion, command=command, device=self.name)
            if status & Status.FAULT:
                self._link.write(Reg.CONTROL, Control.RESET, command=command)
                if not status & Status.HOMED:
                    raise NotReferenced(f"{command} before home()", device=self.name, command=command)
                raise CommandFailed("the device reports a fault", device=self.name, command=command)
            if not status & Status.MOVING:
                return status, at
            if time.monotonic() > deadline:
                raise GripperTimeout(f"not done after {timeout:g} s", device=self.name, command=command)
            time.sleep(POLL_S)

    def _home(self, timeout: float) -> None:
        m = self.limits
        self._go("home", m.max_width, m.min_speed + 0.5 * (m.max_speed - m.min_speed), m.min_force, timeout)

    def _move(self, width: float, speed: float, timeout: float) -> MotionResult:
        status, at = self._go("move", width, speed, self.limits.min_force, timeout)
        if status & Status.OBJECT and abs(at - width) > MotionBlocked.MARGIN:
            raise MotionBlocked(width=at, target=width, device=self.name, command="move")
        return MotionResult(at, GraspState.IDLE)

    def _grasp(self, width: float, speed: float, force: float, timeout: float) -> GraspResult:
        status, at = self._go("grasp", self.limits.min_width, speed, force, timeout)  # close until a part
        if status & Status.OBJECT:
            return GraspResult(True, at, force, GraspState.HOLDING)
        return GraspResult(False, at, None, GraspState.NO_PART, reason="closed without meeting a part")

    def _release(self, width: float, speed: float, timeout: float) -> MotionResult:
        _, at = self._go("release", width, speed, self.limits.min_force, timeout)
        return MotionResult(at, GraspState.IDLE)

    def _stop(self) -> None:
        self._epochs.begin("aborted by stop()")
        self._link.write(Reg.CONTROL, Control.STOP, command="stop")

    def _fast_stop(self) -> None:  # no brake: a stop, latched here until acknowledge()
        self._latched = True
        self._epochs.begin("aborted by fast_stop()")
        self._link.write(Reg.CONTROL, Control.STOP, command="fast_stop")

    def _supersede(self) -> None:  # the R1 takes a new target mid-motion: no stop in between
        self._epochs.begin("superseded by a newer motion before it ended")

    def _acknowledge(self) -> None:
        self._link.write(Reg.CONTROL, Control.RESET, command="acknowledge")
        self._latched = False

    def _state(self) -> GripperState:
        status, at = self._status("state")
        grasp = GraspState.HOLDING if status & Status.OBJECT else GraspState.IDLE
        return GripperState(
            width=at,
            speed=None,
            force=None,
            current=None,
            grasp=GraspState.POSITIONING if status & Status.MOVING else grasp,
            moving=bool(status & Status.MOVING),
            referenced=bool(status & Status.HOMED),
            faults=(("fault",) if status & Status.FAULT else ()) + (("fast_stop",) if self._latched else ()),
            timestamp=time.time(),
        )

    def _info(self) -> DeviceInfo:
        p = self.profile
        status, _ = self._status("info")
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

    def _close(self) -> None:
        self._link.close()

    def _reconnect(self) -> None:  # reconnect=true: a fresh link on the same URL once the device answers
        new = self._connect()
        try:
            new.read(Reg.STATUS, 1, "reconnect")
        except BaseException:
            new.close()
            raise
        old, self._link = self._link, new
        old.close()


class AcmeBackend:
    """What the ``grippers.backends`` entry point names: the family's name, its profile model, and hooks."""

    family = "acme"
    profile_model = AcmeProfile
    default_profile = "acme-r1"  # `grippers sim acme` without --model
    sim_help = "simulate an ACME R1 gripper on loopback TCP"
    sim_example = "grippers sim acme --listen tcp://127.0.0.1:5500 --part-width 30"

    def open(self, url: ConnectionURL, profile: ProfileBase | None, settings: Settings) -> AcmeGripper:
        from grippers.profiles import load_profile

        profile = profile or load_profile(self.default_profile)
        if not isinstance(profile, AcmeProfile):
            raise URLError(f"{url.url}: profile {profile.name!r} is not an ACME profile")
        if url.transport != "tcp" or not url.host:
            raise URLError(f"{url.url}: an ACME gripper speaks TCP (acme+tcp://HOST[:PORT])")
        host, port = url.host, url.port or profile.acme.tcp_port
        timeout = settings.positive("timeout", profile.acme.timeout_s)
        settings.check()  # a misspelt ?timout= is a URLError now, before anything is opened
        return AcmeGripper(lambda: AcmeLink(host, port, timeout=timeout, device=url.url), profile, url.url)

    def simulator(self, profile: ProfileBase, settings: Settings, listen: str | None = None) -> AcmeServer:
        """A simulated R1 on loopback TCP (``listen``: tcp://127.0.0.1:PORT, default a free port)."""
        from .sim import AcmeModel, AcmeServer  # imported when a simulator is started

        assert isinstance(profile, AcmeProfile)
        host, _, port = (listen or "tcp://127.0.0.1:0").removeprefix("tcp://").rpartition(":")
        if not host or not port.isdigit():
            raise URLError(f"{listen}: the ACME simulator listens on tcp://HOST:PORT")
        part = settings.float("part_width_mm", profile.acme.part_width_mm)
        model = AcmeModel(profile.mechanics.stroke_mm, part)
        return AcmeServer(model, host, int(port), time_scale=settings.positive("time_scale", 1.0))

    def simulate(self, profile: ProfileBase, settings: Settings) -> AcmeServer:
        return self.simulator(profile, settings)

    def dissector(self) -> Any:
        """``grippers monitor``: the R1's frames in a byte capture or through the TCP proxy."""
        from grippers.backends import Dissector

        from .codec import AcmeDissector

        return Dissector("acme", stream=AcmeDissector, tcp_port=AcmeSection().tcp_port)

    def probe_candidates(
        self, transport: str, where: ConnectionURL, options: dict[str, Any]
    ) -> list[ProbeCandidate]:
        """``grippers probe tcp://HOST``: try the R1's port there too."""
        if transport != "tcp" or not where.host:
            return []
        return [ProbeCandidate(f"acme+tcp://{where.host}:{where.port or AcmeSection().tcp_port}", order=60)]
