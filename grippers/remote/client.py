"""``zenoh://NAME?connect=tcp/HOST:7447``: a served gripper behind the ordinary :class:`Gripper` API.

A :class:`RemoteDevice` (the device contract, grippers/device.py) held by a :class:`RemoteGripper`, which is
a Gripper plus the control lease (``control()``, ``acquire_control()``, ``release_control()``). Limits come
from the served info and are checked by the gripper before anything is sent (and again by the server);
errors arrive as a class name and are raised as the same class; ``stream()`` is a Zenoh subscription to
the published states (the device's ``state_source`` feature), not polling; ``connected`` and
``on_connection`` follow the server's liveliness (its ``liveness`` feature). The Zenoh side is
grippers/remote/link.py.
"""

from __future__ import annotations

import os
import socket
from typing import Any

from ..device import Device, DeviceContext
from ..drivers.urls import zenoh_endpoints
from ..errors import GripperError, ProtocolError, URLError
from ..gripper import Capability, DeviceInfo, GraspResult, Gripper, GripperState, MotionResult
from ..profiles import Limits, ProfileBase, parse_profile
from ..servo import ServoTarget
from . import payloads, protocol
from .link import ServedLink
from .session import make_config

DEFAULT_TIMEOUT = 2.0
DEFAULT_LINK_LEASE = 1.0  # s; matches the server's default --lease-timeout
MAX_LABEL = protocol.MAX_LABEL  # protocol.parse_request's bound on a request's label


class ZenohBackend:
    """The ``zenoh`` family of the backend table: no profile of its own, the served one is used."""

    family = "zenoh"
    profile_model = None

    def open(self, url: Any, profile: ProfileBase | None, settings: Any) -> RemoteGripper:
        name = url.channel or ""
        if not name:
            raise URLError(f"{url.url}: name the served gripper (zenoh://NAME?connect=tcp/HOST:7447)")
        try:
            protocol.check_name(name)
        except ValueError as exc:
            raise URLError(f"{url.url}: {exc}") from None
        connect = zenoh_endpoints(settings.str("connect", ""), f"{url.url}: connect")
        config_file = settings.str("zenoh_config", None)
        scout = settings.bool("scout", False)
        if not (connect or config_file or scout):
            raise URLError(
                f"{url.url}: say where the server is: ?connect=tcp/HOST:7447 (or zenoh_config=, scout=1)"
            )
        config = make_config(
            mode=settings.str("mode", "client"),
            listen=[],
            connect=connect,
            config_file=config_file,
            scout=scout,
            # The link lease this session announces: how long the server waits on a silent link before our
            # token (and the control lease with it) goes away. Zenoh's default is 10 s.
            lease_s=settings.positive("lease", DEFAULT_LINK_LEASE),
        )
        timeout = settings.positive("timeout", DEFAULT_TIMEOUT)
        label = settings.str("label", f"{socket.gethostname()} pid {os.getpid()}")
        if len(label) > MAX_LABEL:  # the server refuses such a request: said at open, not at every command
            raise URLError(f"{url.url}: label is {len(label)} characters long; at most {MAX_LABEL}")
        try:
            protocol.check_label(label)
        except ValueError as exc:
            raise URLError(f"{url.url}: {exc}") from None
        settings.check()  # a misspelt setting is refused before the session opens
        device = RemoteDevice(ServedLink(url.url, name, config, timeout=timeout, label=label), profile)
        try:
            return RemoteGripper(device, device.profile, url.url, timeout=timeout)
        except BaseException:
            device.close()
            raise


class RemoteDevice(Device):
    """A gripper served by ``grippers serve``, as a device: each primitive is one served verb."""

    reports_fast_stop = True  # the served state says whether the served gripper's fast stop is latched
    fast_stop_shared = True  # another client may acknowledge it: read before refusing a motion

    def __init__(self, link: ServedLink, profile: ProfileBase | None = None) -> None:
        url = link.url
        self.liveness = self.state_source = self._link = link
        try:
            doc = self._link.info_doc
            # Read with the family's model if installed, else as the generic profile (no vendor code needed).
            served = parse_profile(doc["profile_data"], f"{url} (served profile)", generic=True)
            if profile is not None and profile.name != served.name:
                raise URLError(f"{url}: serves {served.name!r}, not the profile {profile.name!r} asked for")
        except BaseException:
            self._link.close()
            raise
        self.profile = served
        self.url = url
        self.capabilities = frozenset(Capability(c) for c in doc["capabilities"] if c in _CAPS)
        self.profile_assumed = bool(doc.get("profile_assumed", False))  # warned by grippers.open
        self.reconnection = _Reconnection(self)
        self.servo = _Servo(self._link)
        self.temperature = _Temperature(self._link)
        self.soft_limits = _SoftLimits(self._link)
        self.device_tag = _DeviceTag(self._link)

    def bind(self, context: DeviceContext) -> None:
        super().bind(context)
        self._link.context = context

    @property
    def driver(self) -> Any:
        """The Zenoh session underneath (vendor extras stay on the serving machine)."""
        return self._link.session

    def narrow_limits(self, limits: Limits) -> Limits:
        return Limits.model_validate(self._link.info_doc["limits"])  # served, possibly device-narrowed

    # -- the primitives: one served verb each ---------------------------------------------------------------

    def home(self, timeout: float) -> None:
        self._link.command("home", timeout, timeout=timeout)

    def move(self, width: float, speed: float, timeout: float) -> MotionResult:
        doc = self._link.command("move", timeout, width=width, speed=speed, timeout=timeout)
        return payloads.motion_from(doc, self.name, "move")

    def grasp(self, width: float, speed: float, force: float, timeout: float) -> GraspResult:
        doc = self._link.command("grasp", timeout, width=width, speed=speed, force=force, timeout=timeout)
        return payloads.grasp_from(doc, self.name)

    def release(self, width: float, speed: float, timeout: float) -> MotionResult:
        doc = self._link.command("release", timeout, width=width, speed=speed, timeout=timeout)
        return payloads.motion_from(doc, self.name, "release")

    def stop(self) -> None:
        self._link.command("stop")

    def fast_stop(self) -> None:
        self._link.command("fast_stop")

    def acknowledge(self) -> None:
        self._link.command("acknowledge")

    def read_state(self) -> GripperState:
        return payloads.state_from(
            self._link.read(protocol.state_key(self._link.served_name), "state"), self.name
        )[1]

    def info(self) -> DeviceInfo:
        doc = self._link.query(protocol.info_key(self._link.served_name), b"", "info", self._link.timeout)
        return payloads.info_from(doc, self.url, self.name)

    def close(self) -> None:
        self._link.close()


class _Reconnection:
    """reconnect=true: the Zenoh session re-establishes its links by itself (its connect retries); the
    served gripper is back when a server answers for it again."""

    def __init__(self, device: RemoteDevice) -> None:
        self.link = device._link

    def alive(self) -> bool:
        return self.link.lost is None  # the server withdrew the gripper's token; a silent one: the heartbeat

    def identity(self) -> dict[str, str]:
        return {}

    def reconnect(self) -> None:
        # Proof, not a flag: an info query that a server answers (ConnectionLost within the timeout if none).
        link = self.link
        link.info_doc = link.query(protocol.info_key(link.served_name), b"", "info", link.timeout)
        link.lost = None
        # The lease ends with the outage: given back if the server still keeps it for us, so that motion
        # resumes only by a new command, which takes a fresh lease (issue 31 §2).
        link.holder.give_back(link.control_query, link.timeout)


class _Servo:
    def __init__(self, link: ServedLink) -> None:
        self.link = link

    def begin(self) -> None:
        """Nothing to prepare here: the server's gripper begins servoing with the first target it takes."""

    def send(self, target: ServoTarget) -> bool:
        # One query per target, from the servo thread only (so targets arrive in order); targets that come
        # while one is in flight are coalesced by the ServoLoop: latest wins here, and again on the server.
        # The server answers once its gripper's own slot holds the target (limits and lease checked there).
        self.link.command("servo", width=target.width, speed=target.speed, force=target.force)
        return True

    def end(self) -> None:
        return None


class _Temperature:
    def __init__(self, link: ServedLink) -> None:
        self.link = link

    def read(self) -> float:
        value = self.link.command("temperature")
        if isinstance(value, bool) or not isinstance(value, int | float):
            raise ProtocolError(
                f"temperature is not a number: {value!r}", device=self.link.name, command="temperature"
            )
        return float(value)


class _SoftLimits:
    def __init__(self, link: ServedLink) -> None:
        self.link = link

    def set(self, min_width: float | None, max_width: float | None) -> None:
        if min_width is None or max_width is None:
            self.link.command("clear_soft_limits")
        else:
            self.link.command("set_soft_limits", min_width=min_width, max_width=max_width)


class _DeviceTag:
    def __init__(self, link: ServedLink) -> None:
        self.link = link

    def read(self) -> str:
        return str(self.link.command("device_tag"))

    def write(self, tag: str) -> None:
        self.link.command("set_device_tag", tag=tag)


class RemoteGripper(Gripper):
    """A :class:`Gripper` holding a :class:`RemoteDevice`, plus the control lease (docs/remote.md).

    The secret arrives in the reply to the request that took the lease and goes with every later command
    and every heartbeat; it is dropped when the server says the lease has ended (AccessDenied to a request
    that carried it), so the next command takes a free lease anew: never a silent re-take of a lease lost
    behind the user's back (a lost link is final without reconnect=true, and ends servoing with it)."""

    device: RemoteDevice

    @property
    def client_id(self) -> str:
        """This client's public id (the server's list of holders names it; the secret stays here)."""
        return self.device._link.client_id

    def control(self) -> _Control:
        """``with g.control():`` holds the control lease (AccessDenied if another client has it) and frees
        it at the end; without it, the first motion command takes the lease and keeps it until close()."""
        return _Control(self)

    def acquire_control(self) -> None:
        self._check_open("control")
        self.device._link.call("control", {"action": "acquire"})

    def release_control(self) -> None:
        self._check_open("control")
        self.device._link.call("control", {"action": "release"})
        self.device._link.holder.secret = None


_CAPS = {c.value for c in Capability}


class _Control:
    def __init__(self, gripper: RemoteGripper) -> None:
        self.gripper = gripper

    def __enter__(self) -> RemoteGripper:
        self.gripper.acquire_control()
        return self.gripper

    def __exit__(self, *exc: object) -> None:
        if self.gripper.connected:
            try:
                self.gripper.release_control()
            except GripperError:
                pass
