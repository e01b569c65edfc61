"""Device profiles: what a model is, how to reach it, and the limits the library enforces.

A profile is a TOML file (YAML with the ``yaml`` extra) validated by the pydantic models below. Values are
in the units people read on datasheets (mm, mm/s, N, mA); the backends convert to SI once. Profiles are found
on a search path so users add their own without touching the package: an explicit file, then
``GRIPPERS_PROFILE_PATH`` (directories or files, ``os.pathsep``-separated), then the user's config directory
(``$XDG_CONFIG_HOME/grippers/profiles``, default ``~/.config/grippers/profiles``), then the built-ins shipped
as the data package ``grippers._profiles``.
"""

from __future__ import annotations

import json
import logging
import os
import re
import tomllib
from collections.abc import Iterator
from importlib import resources
from pathlib import Path
from typing import Annotated, Any, Literal

from pydantic import BaseModel, ConfigDict, Field, TypeAdapter, ValidationError, model_validator

from .errors import ProfileError

log = logging.getLogger(__name__)

PROFILE_SUFFIXES = (".toml", ".yaml", ".yml", ".json")

NonNegative = Annotated[float, Field(ge=0)]
Positive = Annotated[float, Field(gt=0)]
Port = Annotated[int, Field(ge=1, le=65535)]
CanId = Annotated[int, Field(ge=0, le=0x7FF)]  # standard 11-bit identifiers


class _Model(BaseModel):
    # Unknown keys are refused so a typo in a profile is an error, not a silently ignored setting.
    model_config = ConfigDict(extra="forbid", frozen=True)


class Mechanics(_Model):
    """The mechanism's own range (datasheet or device), in mm, mm/s, mm/s² and N."""

    stroke_mm: Positive
    min_width_mm: NonNegative = 0.0
    min_speed_mm_s: NonNegative
    max_speed_mm_s: Positive
    default_speed_mm_s: Positive
    min_accel_mm_s2: NonNegative | None = None
    max_accel_mm_s2: Positive | None = None
    min_force_n: NonNegative
    max_force_n: Positive
    default_force_n: Positive

    @property
    def max_width_mm(self) -> float:
        return self.min_width_mm + self.stroke_mm

    @model_validator(mode="after")
    def _ordered(self) -> Mechanics:
        if not self.min_speed_mm_s <= self.default_speed_mm_s <= self.max_speed_mm_s:
            raise ValueError("needs min_speed_mm_s <= default_speed_mm_s <= max_speed_mm_s")
        if not self.min_force_n <= self.default_force_n <= self.max_force_n:
            raise ValueError("needs min_force_n <= default_force_n <= max_force_n")
        if (
            self.min_accel_mm_s2 is not None
            and self.max_accel_mm_s2 is not None
            and self.min_accel_mm_s2 > self.max_accel_mm_s2
        ):
            raise ValueError("needs min_accel_mm_s2 <= max_accel_mm_s2")
        return self


class Safety(_Model):
    """Limits the library enforces below the mechanism's own: beyond them, refused before sending."""

    max_force_n: Positive | None = None
    max_speed_mm_s: Positive | None = None
    min_width_mm: NonNegative | None = None
    max_width_mm: Positive | None = None
    max_current_ma: Annotated[int, Field(gt=0, le=2800)] | None = None  # MSG: the driver can push 2800 mA


class Limits(_Model):
    """The effective limits (mechanics narrowed by safety) in SI units: what the API checks against."""

    min_width: float
    max_width: float
    min_speed: float
    max_speed: float
    min_force: float
    max_force: float
    max_current: float | None = None  # A, devices that control current instead of force

    @property
    def stroke(self) -> float:
        return self.max_width - self.min_width


class Connection(_Model):
    """Automatic reconnection (grippers/reconnect.py); URL parameters and keywords of the same names win."""

    reconnect: bool = False
    reconnect_backoff_s: Positive = 0.1  # first retry after this, doubling up to the maximum
    reconnect_backoff_max_s: Positive = 5.0
    heartbeat_s: Positive = 0.5  # a state query this often notices a link that died while idle
    acknowledge_on_reconnect: bool = False  # a safety decision: off unless the application says so


class ProfileBase(_Model):
    name: Annotated[str, Field(pattern=r"^[a-z0-9][a-z0-9._-]*$")]
    family: str
    vendor: str
    model: str
    aliases: list[str] = []
    description: str = ""
    source: str = ""  # where the numbers come from
    url: str  # default connection URL
    mechanics: Mechanics
    safety: Safety = Safety()
    connection: Connection = Connection()
    path: Annotated[str | None, Field(exclude=True)] = None  # the file it was read from

    def limits(self) -> Limits:
        m, s = self.mechanics, self.safety
        max_current = getattr(self, "effective_max_current_ma", None)
        return Limits(
            min_width=max(m.min_width_mm, s.min_width_mm or 0.0) / 1000,
            max_width=min(m.max_width_mm, s.max_width_mm or m.max_width_mm) / 1000,
            min_speed=m.min_speed_mm_s / 1000,
            max_speed=min(m.max_speed_mm_s, s.max_speed_mm_s or m.max_speed_mm_s) / 1000,
            min_force=m.min_force_n,
            max_force=min(m.max_force_n, s.max_force_n or m.max_force_n),
            max_current=None if max_current is None else max_current / 1000,
        )

    def matches(self, name: str) -> bool:
        key = _key(name)
        return key == _key(self.name) or any(key == _key(a) for a in self.aliases)


# --- WSG ------------------------------------------------------------------------------------------------


class WsgTransport(_Model):
    # Defaults from PROTOCOL-NOTES §1 "Transport defaults" (public drivers and set-up notes, not the manuals).
    timeout_s: Positive = 1.0
    tcp_port: Port = 1000
    udp_port: Port = 1500
    udp_local_port: Annotated[int, Field(ge=0, le=65535)] = 1501
    baudrate: Annotated[int, Field(gt=0)] = 115200
    bytesize: Literal[5, 6, 7, 8] = 8
    parity: Literal["N", "E", "O", "M", "S"] = "N"
    stopbits: Literal[1, 1.5, 2] = 1  # one public driver uses 2
    can_interface: str = "socketcan"
    can_channel: str = "can0"
    can_bitrate: Annotated[int, Field(gt=0)] = 500_000
    can_send_id: CanId = 0x000  # host -> gripper
    can_recv_id: CanId = 0x001  # gripper -> host
    verify_checksum: bool = True


class WsgDevice(_Model):
    device_type: Annotated[int, Field(ge=0, le=255)]  # 50h TYPE: 1 WSG 50, 2 WSG 32, 5 WSG 25, 6 WSG 70
    # Set in the web interface: how far past the nominal width Grip Part (25h) may close (PROTOCOL-NOTES §1).
    clamping_travel_mm: NonNegative = 10.0


class WsgSimulator(_Model):
    firmware: Annotated[str, Field(pattern=r"^\d+\.\d+\.\d+$")] = "4.0.1"
    serial: Annotated[int, Field(ge=0, le=0xFFFFFFFF)] = 12345
    part_width_mm: NonNegative | None = None
    force_fingers: bool = False
    time_scale: Positive = 1.0


class WsgProfile(ProfileBase):
    family: Literal["wsg"] = "wsg"
    transport: WsgTransport = WsgTransport()
    wsg: WsgDevice
    simulator: WsgSimulator = WsgSimulator()


# --- MSG on STEPFOC ---------------------------------------------------------------------------------------


class StepfocTransport(_Model):
    timeout_s: Positive = 0.5
    baudrate: Annotated[int, Field(gt=0)] = 256_000  # PROTOCOL-NOTES §2 UART
    can_interface: str = "socketcan"
    can_channel: str = "can0"
    can_bitrate: Annotated[int, Field(gt=0)] = 1_000_000  # PROTOCOL-NOTES §2 CAN
    node: Annotated[int, Field(ge=0, le=15)] = 0


class MsgMaps(_Model):
    """How the driver's raw bytes and milliamps relate to width, speed and force.

    Position: byte 0 is fully open, 255 fully closed, linear between the calibrated end stops
    (PROTOCOL-NOTES §2). Speed: byte 0..255 maps linearly to about 500..60000 encoder ticks/s; the mm/s at
    both ends depend on the rail's gearing and are estimates to calibrate per unit. Force: the MSG has no
    force sensor; force is estimated from the current limit.
    """

    open_width_mm: NonNegative
    closed_width_mm: NonNegative = 0.0
    speed_at_0_mm_s: Positive
    speed_at_255_mm_s: Positive
    newton_per_amp: Positive
    min_current_ma: Annotated[int, Field(ge=0)] = 150  # below about 150 mA the motion is unstable (MSG doc)
    max_current_ma: Annotated[int, Field(gt=0, le=2800)] = 1000  # MSG doc: 0-1000 mA
    default_current_ma: Annotated[int, Field(gt=0)] = 500
    grasp_travel_mm: NonNegative = 10.0  # a grasp commands this far inside the nominal width
    inside_grip: bool = False  # a part gripped from inside (object detected while opening)

    @model_validator(mode="after")
    def _ordered(self) -> MsgMaps:
        if self.open_width_mm <= self.closed_width_mm:
            raise ValueError("needs open_width_mm > closed_width_mm")
        if self.speed_at_255_mm_s <= self.speed_at_0_mm_s:
            raise ValueError("needs speed_at_255_mm_s > speed_at_0_mm_s")
        if not self.min_current_ma <= self.default_current_ma <= self.max_current_ma:
            raise ValueError("needs min_current_ma <= default_current_ma <= max_current_ma")
        return self


class MsgSimulator(_Model):
    part_width_mm: NonNegative | None = None
    hardware_version: Annotated[int, Field(ge=0, le=255)] = 1
    software_version: Annotated[int, Field(ge=0, le=255)] = 1
    serial: int = 1001
    time_scale: Positive = 1.0


class MsgProfile(ProfileBase):
    family: Literal["stepfoc"] = "stepfoc"
    transport: StepfocTransport = StepfocTransport()
    maps: MsgMaps
    simulator: MsgSimulator = MsgSimulator()

    @property
    def effective_max_current_ma(self) -> int:
        limit = self.maps.max_current_ma
        if self.safety.max_current_ma is not None:
            limit = min(limit, self.safety.max_current_ma)
        return limit


BUILTIN_PROFILE_MODELS: dict[str, type[ProfileBase]] = {"wsg": WsgProfile, "stepfoc": MsgProfile}
Profile = ProfileBase  # the type users annotate with


# --- loading --------------------------------------------------------------------------------------------


def _key(name: str) -> str:
    return re.sub(r"[^a-z0-9]", "", name.lower())


def _profile_model(family: Any) -> type[ProfileBase]:
    if isinstance(family, str) and family in BUILTIN_PROFILE_MODELS:
        return BUILTIN_PROFILE_MODELS[family]
    if isinstance(family, str):
        from .backends import find_backend

        backend = find_backend(family)
        if backend is not None and getattr(backend, "profile_model", None) is not None:
            return backend.profile_model
    known = ", ".join(sorted(BUILTIN_PROFILE_MODELS))
    raise ValueError(f"family: unknown family {family!r} (built in: {known}; others come from backends)")


def _read(path: Path) -> dict[str, Any]:
    text = path.read_text(encoding="utf-8")
    if path.suffix == ".toml":
        return tomllib.loads(text)
    if path.suffix == ".json":
        return json.loads(text)
    if path.suffix in (".yaml", ".yml"):
        try:
            import yaml  # type: ignore[import-untyped]
        except ImportError:
            raise ProfileError(f"{path}: YAML profiles need: pip install 'grippers[yaml]'") from None
        data = yaml.safe_load(text)
        if not isinstance(data, dict):
            raise ProfileError(f"{path}: a profile is a mapping of fields, not {type(data).__name__}")
        return data
    raise ProfileError(f"{path}: not a profile file (expected one of {', '.join(PROFILE_SUFFIXES)})")


def _format_errors(where: str, exc: ValidationError) -> str:
    parts = []
    for err in exc.errors(include_url=False):
        loc = ".".join(str(p) for p in err["loc"]) or "(top level)"
        parts.append(f"{loc}: {err['msg']}")
    return f"{where}: " + "; ".join(parts)


def parse_profile(data: dict[str, Any], where: str = "<profile>") -> ProfileBase:
    """Validate a mapping as a profile of its family; errors name ``where``, the field and the rule."""
    if not isinstance(data, dict):
        raise ProfileError(f"{where}: a profile is a mapping of fields, not {type(data).__name__}")
    try:
        model = _profile_model(data.get("family"))
    except ValueError as exc:
        raise ProfileError(f"{where}: {exc}") from None
    try:
        profile = model.model_validate(data)
    except ValidationError as exc:
        raise ProfileError(_format_errors(where, exc)) from None
    return profile.model_copy(update={"path": where})


def load_file(path: str | os.PathLike[str]) -> ProfileBase:
    p = Path(path)
    try:
        data = _read(p)
    except OSError as exc:
        raise ProfileError(f"{p}: cannot read: {exc.strerror or exc}") from None
    except (tomllib.TOMLDecodeError, json.JSONDecodeError) as exc:
        raise ProfileError(f"{p}: not valid {p.suffix[1:].upper()}: {exc}") from None
    except Exception as exc:  # YAML's errors, without importing yaml here
        if isinstance(exc, ProfileError):
            raise
        raise ProfileError(f"{p}: cannot parse: {exc}") from None
    return parse_profile(data, str(p))


def validate_file(path: str | os.PathLike[str]) -> list[str]:
    """Every problem in one profile file, one line each; empty when it is valid."""
    try:
        load_file(path)
    except ProfileError as exc:
        return [str(exc)]
    return []


def user_profile_dir() -> Path:
    base = os.environ.get("XDG_CONFIG_HOME") or os.path.join(os.path.expanduser("~"), ".config")
    return Path(base) / "grippers" / "profiles"


def _files_in(entry: Path) -> list[Path]:
    if entry.is_file():
        return [entry]
    if entry.is_dir():
        return sorted(p for p in entry.iterdir() if p.suffix in PROFILE_SUFFIXES and p.is_file())
    return []


def search_path() -> list[Path]:
    """Directories and files searched for profiles, first match wins (the built-ins come last)."""
    entries = [Path(e) for e in os.environ.get("GRIPPERS_PROFILE_PATH", "").split(os.pathsep) if e]
    entries.append(user_profile_dir())
    return entries


def _builtin_files() -> list[Path]:
    root = resources.files("grippers._profiles")
    return sorted(Path(str(p)) for p in root.iterdir() if p.name.endswith(PROFILE_SUFFIXES))


def _candidate_files() -> Iterator[Path]:
    for entry in search_path():
        yield from _files_in(entry)
    yield from _builtin_files()


def list_profiles(*, strict: bool = True) -> list[ProfileBase]:
    """Every profile on the search path; a user's file shadows a built-in of the same name.

    ``strict=False`` skips (and logs) files that do not validate: a lookup by alias or WSG device type must
    not fail because of an unrelated broken file in the user's directory.
    """
    seen: dict[str, ProfileBase] = {}
    for path in _candidate_files():
        try:
            profile = load_file(path)
        except ProfileError as exc:
            if strict:
                raise
            log.warning("skipping a profile that does not validate: %s", exc)
            continue
        seen.setdefault(profile.name, profile)
    return list(seen.values())


def _looks_like_path(name: str) -> bool:
    return name.endswith(PROFILE_SUFFIXES) or os.sep in name or "/" in name


def load_profile(name: str | os.PathLike[str]) -> ProfileBase:
    """A profile by file path, name or alias (``wsg50``, ``WSG 50``, ``msg-150``)."""
    text = os.fspath(name)
    if _looks_like_path(text):
        return load_file(text)
    for path in _candidate_files():
        # The file name is the cheap test; aliases need the file's contents.
        if _key(path.stem) == _key(text):
            return load_file(path)
    profiles = list_profiles(strict=False)
    for profile in profiles:
        if profile.matches(text):
            return profile
    names = ", ".join(sorted(p.name for p in profiles))
    raise ProfileError(f"no profile named {text!r} (known: {names}; search path: {_describe_path()})")


def _describe_path() -> str:
    return os.pathsep.join(str(p) for p in search_path()) + os.pathsep + "<built-in>"


def wsg_profile_for_device_type(device_type: int) -> WsgProfile | None:
    """The built-in or user profile of the WSG model that reports ``device_type`` in 50h."""
    for profile in list_profiles(strict=False):
        if isinstance(profile, WsgProfile) and profile.wsg.device_type == device_type:
            return profile
    return None


def json_schema() -> dict[str, Any]:
    """JSON Schema of every built-in family's profile, for editors (``grippers profiles schema``)."""
    union = Annotated[WsgProfile | MsgProfile, Field(discriminator="family")]
    return TypeAdapter(union).json_schema()
