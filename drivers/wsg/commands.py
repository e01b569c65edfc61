"""The WSG command set as one table, and the typed values its replies carry (sans-IO).

Every command of the 4.0.x and 2.2.0 manuals is described once in :data:`COMMANDS`; request builders and
decoders (client and simulator), reply builders and decoders, and the monitor's one-line text all read that
table, so a layout cannot drift between the two sides. Errata of docs/protocols.md §1 are applied and marked.
"""

from __future__ import annotations

import struct
from collections.abc import Callable, Mapping
from dataclasses import dataclass, field
from enum import IntEnum, IntFlag
from typing import Any

from ..errors import LimitError, ProtocolError
from ..numbers import finite
from .protocol import Packet, Status, slot_setter, status_name, to_status

__all__ = [
    "COMMANDS",
    "AUTO_UPDATE_COMMANDS",
    "CommandSpec",
    "Cmd",
    "DeviceType",
    "Field",
    "FingerFlags",
    "FingerInfo",
    "FingerType",
    "FirmwareVersion",
    "GraspingState",
    "GraspingStatistics",
    "Layout",
    "Reply",
    "RequestFormatError",
    "SoftLimits",
    "SystemFlags",
    "SystemInfo",
    "SystemLimits",
    "command_name",
    "decode_reply",
    "decode_request",
    "describe",
    "encode_reply",
    "encode_request",
    "spec",
]


class Cmd(IntEnum):
    """Command ids of both manuals (4.0.x §3, 2.2.0 §3)."""

    LOOP = 0x06
    DISCONNECT = 0x07
    HOMING = 0x20
    PREPOSITION = 0x21
    STOP = 0x22
    FAST_STOP = 0x23
    ACK_FAST_STOP = 0x24
    GRIP = 0x25
    RELEASE = 0x26
    SET_ACCELERATION = 0x30
    GET_ACCELERATION = 0x31
    SET_FORCE_LIMIT = 0x32
    GET_FORCE_LIMIT = 0x33
    SET_SOFT_LIMITS = 0x34
    GET_SOFT_LIMITS = 0x35
    CLEAR_SOFT_LIMITS = 0x36
    OVERDRIVE = 0x37
    TARE = 0x38
    GET_SYSTEM_STATE = 0x40
    GET_GRASPING_STATE = 0x41
    GET_GRASPING_STATISTICS = 0x42
    GET_WIDTH = 0x43
    GET_SPEED = 0x44
    GET_FORCE = 0x45
    GET_TEMPERATURE = 0x46
    GET_SYSTEM_INFO = 0x50
    SET_DEVICE_TAG = 0x51
    GET_DEVICE_TAG = 0x52
    GET_SYSTEM_LIMITS = 0x53
    GET_FINGER1_INFO = 0x60
    GET_FINGER1_FLAGS = 0x61
    FINGER1_POWER = 0x62
    GET_FINGER1_DATA = 0x63
    GET_FINGER2_INFO = 0x70
    GET_FINGER2_FLAGS = 0x71
    FINGER2_POWER = 0x72
    GET_FINGER2_DATA = 0x73


# ---------------------------------------------------------------------------------------------- typed values


class SystemFlags(IntFlag):
    """System state flags, WSG manual 4.0.x Appendix B (same bits in 2.2.0 Appendix B)."""

    SF_REFERENCED = 1 << 0
    SF_MOVING = 1 << 1
    SF_BLOCKED_MINUS = 1 << 2
    SF_BLOCKED_PLUS = 1 << 3
    SF_SOFT_LIMIT_MINUS = 1 << 4
    SF_SOFT_LIMIT_PLUS = 1 << 5
    SF_AXIS_STOPPED = 1 << 6
    SF_TARGET_POS_REACHED = 1 << 7
    SF_OVERDRIVE_MODE = 1 << 8
    SF_FORCECNTL_MODE = 1 << 9
    SF_FAST_STOP = 1 << 12
    SF_TEMP_WARNING = 1 << 13
    SF_TEMP_FAULT = 1 << 14
    SF_POWER_FAULT = 1 << 15
    SF_CURR_FAULT = 1 << 16
    SF_FINGER_FAULT = 1 << 17
    SF_CMD_FAILURE = 1 << 18
    SF_SCRIPT_RUNNING = 1 << 19
    SF_SCRIPT_FAILURE = 1 << 20


class GraspingState(IntEnum):
    """Grasping ("gripper") state, WSG manual 4.0.x §3.4.2; ERROR (7) is new in 4.x (reserved in 2.2.0)."""

    IDLE = 0
    GRASPING = 1
    GRIPPING = 1  # alias: the 4.0.x text calls it "Grasping", the contracts "GRIPPING"
    NO_PART = 2
    PART_LOST = 3
    HOLDING = 4
    RELEASING = 5
    POSITIONING = 6
    ERROR = 7


class DeviceType(IntEnum):
    """Device type of 50h, WSG manual 4.0.x §3.5.1 and docs/protocols.md §1."""

    UNKNOWN = 0
    WSG50 = 1
    WSG32 = 2
    KMS40 = 3
    WTS = 4
    WSG25 = 5
    WSG70 = 6


class FingerType(IntEnum):
    """Finger type of 60h/70h, WSG manual 4.0.x §3.6.1."""

    GENERIC = 0  # or no finger installed
    WSG_FMF = 1
    WSG_DSA = 2


class FingerFlags(IntFlag):
    """Finger state flags of 61h/71h (u16), WSG manual 4.0.x §3.6.2."""

    POWER_ON = 1 << 0
    CONFIG_AVAIL = 1 << 1
    COMM_OPEN = 1 << 2
    POWER_FAULT = 1 << 8
    COMM_FAULT = 1 << 9


@dataclass(frozen=True, slots=True, order=True)
class FirmwareVersion:
    """Firmware version from 50h: four nibbles of a u16, D15..12 major (WSG manual 4.0.x §3.5.1)."""

    major: int
    minor1: int
    minor2: int
    rc: int = 0  # 0 = release, 1..15 = release candidate

    def __post_init__(self) -> None:
        for name in ("major", "minor1", "minor2", "rc"):
            value = getattr(self, name)
            if not 0 <= value <= 15:
                raise LimitError(f"firmware version part {name}={value} does not fit a nibble")

    def __str__(self) -> str:
        text = f"{self.major}.{self.minor1}.{self.minor2}"
        return f"{text}-rc{self.rc}" if self.rc else text

    @classmethod
    def from_word(cls, word: int) -> FirmwareVersion:
        return cls((word >> 12) & 0xF, (word >> 8) & 0xF, (word >> 4) & 0xF, word & 0xF)

    def to_word(self) -> int:
        return (self.major << 12) | (self.minor1 << 8) | (self.minor2 << 4) | self.rc

    @classmethod
    def parse(cls, text: str) -> FirmwareVersion:
        """``"4.0.1"`` or ``"4.0.1-rc2"``."""
        base, _, rc = text.strip().partition("-rc")
        parts = base.split(".")
        try:
            if len(parts) != 3:
                raise ValueError
            return cls(int(parts[0]), int(parts[1]), int(parts[2]), int(rc) if rc else 0)
        except ValueError:
            raise LimitError(f"not a firmware version: {text!r} (expected e.g. 4.0.1 or 4.0.1-rc2)") from None

    @classmethod
    def coerce(cls, value: FirmwareVersion | str | int) -> FirmwareVersion:
        if isinstance(value, FirmwareVersion):
            return value
        if isinstance(value, str):
            return cls.parse(value)
        return cls.from_word(int(value))


@dataclass(frozen=True, slots=True)
class SystemInfo:
    device_type: DeviceType | int
    hw_revision: int
    firmware: FirmwareVersion
    serial: int


@dataclass(frozen=True, slots=True)
class SystemLimits:
    stroke: float
    min_speed: float
    max_speed: float
    min_acceleration: float
    max_acceleration: float
    min_force: float
    nominal_force: float
    overdrive_force: float


@dataclass(frozen=True, slots=True)
class GraspingStatistics:
    total: int
    no_part: int
    lost_part: int


@dataclass(frozen=True, slots=True)
class SoftLimits:
    minus: float
    plus: float


@dataclass(frozen=True, slots=True)
class FingerInfo:
    finger_type: FingerType | int
    data_size: int


# ------------------------------------------------------------------------------------------------ layouts


class _Missing:
    def __repr__(self) -> str:
        return "<required>"


REQUIRED: Any = _Missing()


def _enum_or_int(enum: type[IntEnum]) -> Callable[[int], Any]:
    def convert(value: int) -> Any:
        try:
            return enum(value)
        except ValueError:
            return value

    return convert


@dataclass(frozen=True, slots=True)
class Field:
    """One field of a request or reply.

    ``fmt`` is a :mod:`struct` code (little-endian, WSG manual 4.0.x §1), ``"3s"`` for fixed bytes, ``"*"``
    for the rest of the payload as bytes or ``"*s"`` as text. ``bits`` splits a flag byte into named
    booleans (the field's own name then never appears in the values). ``to_wire``/``from_wire`` convert
    typed values.
    """

    name: str
    fmt: str
    unit: str = ""
    default: Any = REQUIRED
    bits: tuple[tuple[str, int], ...] = ()
    to_wire: Callable[[Any], Any] | None = None
    from_wire: Callable[[Any], Any] | None = None
    max_len: int | None = None  # for "*" / "*s": longer is a format error (E_CMD_FORMAT_ERROR)

    @property
    def variable(self) -> bool:
        return self.fmt.startswith("*")


class RequestFormatError(ProtocolError):
    """A request payload that does not fit its command; ``status`` is what the device answers."""

    def __init__(self, message: str, *, status: Status, command: str | None = None) -> None:
        self.status = status
        super().__init__(message, command=command)


class Layout:
    """An ordered list of fields compiled into one :class:`struct.Struct` plus an optional variable tail."""

    def __init__(self, *fields: Field) -> None:
        self.fields = fields
        for f in fields[:-1]:
            if f.variable:
                raise ValueError("only the last field may be variable")
        self.tail = fields[-1] if fields and fields[-1].variable else None
        self.fixed = fields[:-1] if self.tail else fields
        self.struct = struct.Struct("<" + "".join(f.fmt for f in self.fixed))
        self.size = self.struct.size
        # A layout of plain fields (no flag bits, no conversion, no tail) unpacks straight into a dict: the
        # replies of the state queries, decoded on every round trip and every auto update.
        plain = self.tail is None and all(not f.bits and f.from_wire is None for f in fields)
        self._plain_names = tuple(f.name for f in fields) if plain else None
        #: One plain field (width, speed, force): :func:`reply_value` unpacks it without building a dict.
        self.single_plain = plain and len(fields) == 1

    @property
    def empty(self) -> bool:
        return not self.fields

    @property
    def names(self) -> tuple[str, ...]:
        names: list[str] = []
        for f in self.fields:
            if f.bits:
                names.extend(name for name, _ in f.bits)
            else:
                names.append(f.name)
        return tuple(names)

    def pack(self, values: Mapping[str, Any], command: str) -> bytes:
        unknown = set(values) - set(self.names)
        if unknown:
            raise ProtocolError(
                f"unknown field(s) {sorted(unknown)}; expected {list(self.names)}", command=command
            )
        raw: list[Any] = []
        for f in self.fixed:
            raw.append(self._to_wire(f, values, command))
        try:
            data = self.struct.pack(*raw)
        except (struct.error, OverflowError, TypeError) as exc:
            raise LimitError(f"value does not fit the wire format: {exc}", command=command) from None
        if self.tail is not None:
            value = self._to_wire(self.tail, values, command)
            if isinstance(value, str):
                try:
                    value = value.encode("ascii")
                except UnicodeEncodeError:
                    raise LimitError(f"{self.tail.name} must be ASCII text", command=command) from None
            data += bytes(value)
        return data

    @staticmethod
    def _to_wire(f: Field, values: Mapping[str, Any], command: str) -> Any:
        if f.bits:
            word = 0
            for name, bit in f.bits:
                if values.get(name, False):
                    word |= 1 << bit
            return word
        value = values.get(f.name, f.default)
        if value is REQUIRED:
            raise ProtocolError(f"missing field {f.name!r}", command=command)
        if f.to_wire is not None:
            value = f.to_wire(value)
        if f.fmt == "f":
            value = float(value)
        return value

    def unpack(self, data: bytes, command: str) -> dict[str, Any]:
        """Values from ``data``; a length that does not fit raises :class:`ProtocolError` saying which."""
        size = self.size
        names = self._plain_names
        if names is not None and len(data) == size:
            plain = self.struct.unpack(data)
            return {names[0]: plain[0]} if len(names) == 1 else dict(zip(names, plain, strict=True))
        if self.tail is None:
            if len(data) != size:
                raise ProtocolError(f"expected {size} data bytes, got {len(data)}", command=command)
        elif len(data) < size:
            raise ProtocolError(f"expected at least {size} data bytes, got {len(data)}", command=command)
        values: dict[str, Any] = {}
        for f, raw in zip(self.fixed, self.struct.unpack_from(data), strict=True):
            if f.bits:
                for name, bit in f.bits:
                    values[name] = bool(raw >> bit & 1)
            else:
                values[f.name] = f.from_wire(raw) if f.from_wire is not None else raw
        if self.tail is not None:
            rest = bytes(data[size:])
            if self.tail.max_len is not None and len(rest) > self.tail.max_len:
                raise ProtocolError(
                    f"{self.tail.name} of {len(rest)} bytes exceeds {self.tail.max_len}", command=command
                )
            value: Any = rest.decode("latin-1").rstrip("\0") if self.tail.fmt == "*s" else rest
            values[self.tail.name] = self.tail.from_wire(value) if self.tail.from_wire else value
        return values


@dataclass(frozen=True, slots=True)
class CommandSpec:
    """One row of the command table."""

    id: int
    name: str
    title: str
    section: str  # WSG manual 4.0.x section
    request: Layout
    reply: Layout
    is_async: bool = False  # may answer E_CMD_PENDING followed by a final reply (§1.3)
    auto_update: bool = False  # request carries auto-update flags + period; updates reuse the id
    min_firmware_major: int = 0  # refused locally below this major version
    result: Callable[..., Any] | None = None  # aggregate type built from the reply fields
    doc: str = field(default="", compare=False)


# -------------------------------------------------------------------------------------------- field helpers


def _f32(name: str, unit: str = "") -> Field:
    # docs/protocols.md §1 errata: every "float" is 4 bytes, even where the 4.0.x manual prints "Byte 0".
    return Field(name, "f", unit)


def _temperature_to_wire(celsius: float) -> int:
    return round(finite(celsius, "temperature", command="GET_TEMPERATURE") * 10)


# docs/protocols.md §1: auto-update parameters: byte 0 flags (D0 on, D1 only on change), bytes 1..2
# period (u16).
_AUTO_UPDATE_FIELDS = (
    Field("flags", "B", bits=(("auto_update", 0), ("changes_only", 1))),
    Field("period_ms", "H", "ms", default=0),
)

_SYSTEM_FLAGS = Field("state", "I", from_wire=lambda raw: SystemFlags(raw), to_wire=int)
_GRASPING_STATE = Field("state", "B", from_wire=_enum_or_int(GraspingState), to_wire=int)
_FIRMWARE = Field(
    "firmware",
    "H",
    from_wire=FirmwareVersion.from_word,
    to_wire=lambda v: FirmwareVersion.coerce(v).to_word(),
)


def _finger(base: int, n: int) -> list[CommandSpec]:
    section = 1 if n == 1 else 5
    return [
        CommandSpec(
            base,
            f"GET_FINGER{n}_INFO",
            f"Get Finger {n} Info",
            f"3.6.{section}",
            Layout(),
            # docs/protocols.md §1 erratum: SIZE is bytes 1..2 (4.0.x §3.6.1 prints 2..3).
            Layout(
                Field("finger_type", "B", from_wire=_enum_or_int(FingerType), to_wire=int),
                Field("data_size", "H", "bytes"),
            ),
            min_firmware_major=3,
            result=FingerInfo,
        ),
        CommandSpec(
            base + 1,
            f"GET_FINGER{n}_FLAGS",
            f"Get Finger {n} Flags",
            f"3.6.{section + 1}",
            Layout(),
            Layout(Field("flags", "H", from_wire=lambda raw: FingerFlags(raw), to_wire=int)),
            min_firmware_major=3,
        ),
        CommandSpec(
            # docs/protocols.md §1 erratum: the ON/OFF parameter is byte 0 (4.0.x §3.6.3 prints "Byte 1").
            base + 2,
            f"FINGER{n}_POWER",
            f"Finger {n} Power Control",
            f"3.6.{section + 2}",
            Layout(Field("power", "B", to_wire=lambda on: 1 if on else 0, from_wire=bool)),
            Layout(),
            is_async=True,
            min_firmware_major=3,
            doc="pending then success (~500 ms) when switching on; immediate when switching off",
        ),
        CommandSpec(
            base + 3,
            f"GET_FINGER{n}_DATA",
            f"Get Finger {n} Data",
            f"3.6.{section + 3}",
            Layout(),
            Layout(Field("data", "*")),
            min_firmware_major=3,
        ),
    ]


# Firmware 2.2.0 has neither 46h nor the finger commands (docs/protocols.md §1); 4.0.x documents them.
# The 3.x manuals are not among our sources, so 3.x is assumed to have them: a device that lacks one answers
# E_CMD_UNKNOWN, which is harmless, while refusing a command a device has would not be.
def _auto_update(command: Cmd, title: str, section: str, reply: Field) -> CommandSpec:
    """A state query that can also update automatically (manual §3.4): the same request fields for all of
    them, a reply of one field."""
    return CommandSpec(
        command, command.name, title, section, Layout(*_AUTO_UPDATE_FIELDS), Layout(reply), auto_update=True
    )


_SPECS: list[CommandSpec] = [
    CommandSpec(
        Cmd.LOOP,
        "LOOP",
        "Loop",
        "3.1.1",
        Layout(Field("data", "*", max_len=256, default=b"")),
        Layout(Field("data", "*")),
    ),
    CommandSpec(
        Cmd.DISCONNECT,
        "DISCONNECT",
        "Disconnect Announcement",
        "3.1.2",
        Layout(),
        Layout(),
        doc="TCP only; afterwards the device answers E_ACCESS_DENIED until reconnected",
    ),
    CommandSpec(
        Cmd.HOMING,
        "HOMING",
        "Homing",
        "3.2.1",
        Layout(Field("direction", "B", default=0)),
        Layout(),
        is_async=True,
        doc="direction 0: configured default, 1: positive (external), 2: negative (internal)",
    ),
    CommandSpec(
        Cmd.PREPOSITION,
        "PREPOSITION",
        "Pre-position Fingers",
        "3.2.2",
        # docs/protocols.md §1: D0 = relative motion, D1 = stop on block (the manual is right).
        Layout(
            Field("flags", "B", bits=(("relative", 0), ("stop_on_block", 1))),
            _f32("width", "mm"),
            _f32("speed", "mm/s"),
        ),
        Layout(),
        is_async=True,
    ),
    CommandSpec(Cmd.STOP, "STOP", "Stop", "3.2.3", Layout(), Layout()),
    CommandSpec(Cmd.FAST_STOP, "FAST_STOP", "Issue FAST STOP", "3.2.4", Layout(), Layout()),
    CommandSpec(
        Cmd.ACK_FAST_STOP,
        "ACK_FAST_STOP",
        "Acknowledge FAST STOP",
        "3.2.5",
        # docs/protocols.md §1: the key is the three ASCII bytes "ack".
        Layout(
            Field(
                "key",
                "3s",
                default=b"ack",
                to_wire=lambda k: k.encode("ascii") if isinstance(k, str) else bytes(k),
            )
        ),
        Layout(),
    ),
    CommandSpec(
        Cmd.GRIP,
        "GRIP",
        "Grip Part",
        "3.2.6",
        Layout(_f32("width", "mm"), _f32("speed", "mm/s")),
        Layout(),
        is_async=True,
    ),
    CommandSpec(
        Cmd.RELEASE,
        "RELEASE",
        "Release Part",
        "3.2.7",
        Layout(_f32("width", "mm"), _f32("speed", "mm/s")),
        Layout(),
        is_async=True,
    ),
    CommandSpec(
        Cmd.SET_ACCELERATION,
        "SET_ACCELERATION",
        "Set Acceleration",
        "3.3.1",
        Layout(_f32("acceleration", "mm/s²")),
        Layout(),
    ),
    CommandSpec(
        Cmd.GET_ACCELERATION,
        "GET_ACCELERATION",
        "Get Acceleration",
        "3.3.2",
        Layout(),
        Layout(_f32("acceleration", "mm/s²")),
    ),
    CommandSpec(
        Cmd.SET_FORCE_LIMIT,
        "SET_FORCE_LIMIT",
        "Set Force Limit",
        "3.3.3",
        Layout(_f32("force", "N")),
        Layout(),
    ),
    CommandSpec(
        Cmd.GET_FORCE_LIMIT,
        "GET_FORCE_LIMIT",
        "Get Force Limit",
        "3.3.4",
        Layout(),
        Layout(_f32("force", "N")),
    ),
    CommandSpec(
        Cmd.SET_SOFT_LIMITS,
        "SET_SOFT_LIMITS",
        "Set Soft Limits",
        "3.3.5",
        Layout(_f32("minus", "mm"), _f32("plus", "mm")),
        Layout(),
    ),
    CommandSpec(
        Cmd.GET_SOFT_LIMITS,
        "GET_SOFT_LIMITS",
        "Get Soft Limits",
        "3.3.6",
        Layout(),
        Layout(_f32("minus", "mm"), _f32("plus", "mm")),
        result=SoftLimits,
    ),
    CommandSpec(Cmd.CLEAR_SOFT_LIMITS, "CLEAR_SOFT_LIMITS", "Clear Soft Limits", "3.3.7", Layout(), Layout()),
    CommandSpec(
        Cmd.OVERDRIVE,
        "OVERDRIVE",
        "Overdrive Mode",
        "3.3.8",
        Layout(Field("flags", "B", bits=(("enable", 0),))),
        Layout(),
    ),
    CommandSpec(Cmd.TARE, "TARE", "Tare Force Sensor", "3.3.9", Layout(), Layout()),
    _auto_update(Cmd.GET_SYSTEM_STATE, "Get System State", "3.4.1", _SYSTEM_FLAGS),
    _auto_update(Cmd.GET_GRASPING_STATE, "Get Gripper State", "3.4.2", _GRASPING_STATE),
    # docs/protocols.md §1 erratum: the id is 42h (both manuals print "Command ID: 40h").
    CommandSpec(
        Cmd.GET_GRASPING_STATISTICS,
        "GET_GRASPING_STATISTICS",
        "Get Gripping Statistics",
        "3.4.3",
        Layout(Field("flags", "B", bits=(("reset", 0),))),
        Layout(Field("total", "I"), Field("no_part", "H"), Field("lost_part", "H")),
        result=GraspingStatistics,
    ),
    _auto_update(Cmd.GET_WIDTH, "Get Opening Width", "3.4.4", _f32("width", "mm")),
    _auto_update(Cmd.GET_SPEED, "Get Speed", "3.4.5", _f32("speed", "mm/s")),
    _auto_update(Cmd.GET_FORCE, "Get Force", "3.4.6", _f32("force", "N")),
    # docs/protocols.md §1: i16 in 0.1 °C; decoded to °C as a float.
    CommandSpec(
        Cmd.GET_TEMPERATURE,
        "GET_TEMPERATURE",
        "Get Temperature",
        "3.4.7",
        Layout(),
        Layout(
            Field("temperature", "h", "°C", from_wire=lambda raw: raw / 10.0, to_wire=_temperature_to_wire)
        ),
        min_firmware_major=3,
    ),
    CommandSpec(
        Cmd.GET_SYSTEM_INFO,
        "GET_SYSTEM_INFO",
        "Get System Information",
        "3.5.1",
        Layout(),
        Layout(
            Field("device_type", "B", from_wire=_enum_or_int(DeviceType), to_wire=int),
            Field("hw_revision", "B"),
            _FIRMWARE,
            Field("serial", "I"),
        ),
        result=SystemInfo,
    ),
    CommandSpec(
        Cmd.SET_DEVICE_TAG,
        "SET_DEVICE_TAG",
        "Set Device Tag",
        "3.5.2",
        Layout(Field("tag", "*s")),
        Layout(),
        doc="at most 64 ASCII characters, no control characters",
    ),
    CommandSpec(
        Cmd.GET_DEVICE_TAG, "GET_DEVICE_TAG", "Get Device Tag", "3.5.3", Layout(), Layout(Field("tag", "*s"))
    ),
    CommandSpec(
        Cmd.GET_SYSTEM_LIMITS,
        "GET_SYSTEM_LIMITS",
        "Get System Limits",
        "3.5.4",
        Layout(),
        Layout(
            _f32("stroke", "mm"),
            _f32("min_speed", "mm/s"),
            _f32("max_speed", "mm/s"),
            _f32("min_acceleration", "mm/s²"),
            _f32("max_acceleration", "mm/s²"),
            _f32("min_force", "N"),
            _f32("nominal_force", "N"),
            _f32("overdrive_force", "N"),
        ),
        result=SystemLimits,
    ),
    *_finger(Cmd.GET_FINGER1_INFO, 1),
    *_finger(Cmd.GET_FINGER2_INFO, 2),
]

COMMANDS: dict[int, CommandSpec] = {s.id: s for s in _SPECS}
AUTO_UPDATE_COMMANDS: frozenset[int] = frozenset(s.id for s in _SPECS if s.auto_update)


def spec(cmd: int) -> CommandSpec:
    try:
        return COMMANDS[cmd]
    except KeyError:
        raise ProtocolError(f"unknown command id {cmd:#04x}") from None


def available(cmd: int, firmware: FirmwareVersion | None) -> bool:
    """Whether ``firmware`` has ``cmd``: the one rule behind the client's local refusal (NotSupported), the
    backend's capabilities and the simulator's E_CMD_UNKNOWN, so they cannot disagree.

    An unknown firmware (not read yet) or an id outside the table is given the benefit of the doubt: the
    device itself answers E_CMD_UNKNOWN for what it lacks."""
    s = COMMANDS.get(cmd)
    return firmware is None or s is None or firmware.major >= s.min_firmware_major


_NAMES: dict[int, str] = {cmd: f"{s.name} ({cmd:02X}h)" for cmd, s in COMMANDS.items()}


def command_name(cmd: int) -> str:
    """``"PREPOSITION (21h)"``; never raises."""
    name = _NAMES.get(cmd)
    return name if name is not None else f"command {cmd:02X}h"


# ------------------------------------------------------------------------------------------- codec functions


def encode_request(cmd: int, **fields: Any) -> bytes:
    """Request payload for ``cmd`` from named fields (defaults fill optional ones)."""
    s = spec(cmd)
    return s.request.pack(fields, command_name(cmd))


def decode_request(cmd: int, payload: bytes) -> dict[str, Any]:
    """Named fields of a request payload; raises :class:`RequestFormatError` with the device's answer."""
    s = COMMANDS.get(cmd)
    name = command_name(cmd)
    if s is None:
        raise RequestFormatError("unknown command", status=Status.E_CMD_UNKNOWN, command=name)
    if s.request.empty and payload:
        raise RequestFormatError(
            f"no parameters expected, got {len(payload)} bytes",
            status=Status.E_NO_PARAM_EXPECTED,
            command=name,
        )
    try:
        return s.request.unpack(payload, name)
    except ProtocolError as exc:
        raise RequestFormatError(exc.message, status=Status.E_CMD_FORMAT_ERROR, command=name) from None


@dataclass(frozen=True, slots=True)
class Reply:
    """A decoded reply: status (a :class:`Status`, or an int for codes newer than the manuals) and fields."""

    command: int
    status: Status | int
    fields: dict[str, Any]

    def __init__(self, command: int, status: Status | int, fields: dict[str, Any]) -> None:
        # One per reply: the slot setters take half the time of the generated frozen __init__
        # (docs/performance.md, target 2); the instance stays frozen.
        _set_reply_command(self, command)
        _set_reply_status(self, status)
        _set_reply_fields(self, fields)

    @property
    def ok(self) -> bool:
        return self.status == Status.E_SUCCESS

    @property
    def pending(self) -> bool:
        return self.status == Status.E_CMD_PENDING

    @property
    def status_name(self) -> str:
        return status_name(self.status)

    @property
    def value(self) -> Any:
        """The typed result: the aggregate for multi-field replies, the only field, or None."""
        if not self.ok:
            return None
        s = COMMANDS.get(self.command)
        if s is not None and s.result is not None:
            return s.result(**self.fields)
        if len(self.fields) == 1:
            return next(iter(self.fields.values()))
        return self.fields or None


# Slot setters of a frozen class: the decoder fills replies without __init__ (the fast path, benchmark 4).
_set_reply_command = slot_setter(Reply, "command")
_set_reply_status = slot_setter(Reply, "status")
_set_reply_fields = slot_setter(Reply, "fields")


def encode_reply(cmd: int, status: int = Status.E_SUCCESS, **fields: Any) -> bytes:
    """Reply payload: u16 status, then the data only when status is E_SUCCESS (WSG manual 4.0.x §1.2.2)."""
    head = struct.pack("<H", int(status))
    if status != Status.E_SUCCESS:
        return head
    s = COMMANDS.get(cmd)
    if s is None:
        return head + bytes(fields.get("data", b""))
    return head + s.reply.pack(fields, command_name(cmd))


def decode_reply(cmd: int, payload: bytes) -> Reply:
    """Typed reply; a payload without status, or success data of the wrong length, raises ProtocolError."""
    name = command_name(cmd)
    if len(payload) < 2:
        raise ProtocolError(f"reply of {len(payload)} bytes has no status code", command=name)
    code = payload[0] | (payload[1] << 8)
    if code:  # not E_SUCCESS (the enum lookup is left to the rare case)
        # Data follows only on success; anything else is ignored rather than failing a valid error report.
        return Reply(cmd, to_status(code), {})
    s = COMMANDS.get(cmd)
    if s is None:
        return Reply(cmd, Status.E_SUCCESS, {"data": bytes(payload[2:])})
    return Reply(cmd, Status.E_SUCCESS, s.reply.unpack(payload[2:], name))


def reply_value(cmd: int, payload: bytes) -> Any:
    """``decode_reply(cmd, payload).value``, with the same errors, but a successful reply of one plain field
    is unpacked without the Reply and its dict: the width, speed and force queries that control loops poll
    (docs/performance.md, target 2)."""
    if len(payload) >= 2 and not (payload[0] | payload[1]):
        s = COMMANDS.get(cmd)
        if s is not None and s.reply.single_plain and len(payload) == s.reply.size + 2:
            return s.reply.struct.unpack_from(payload, 2)[0]
    return decode_reply(cmd, payload).value


def _format_value(value: Any) -> str:
    if isinstance(value, float):
        return f"{value:g}"
    if isinstance(value, IntFlag):
        return "|".join(m.name for m in type(value) if m in value and m.name) or "0"
    if isinstance(value, IntEnum):
        return value.name
    if isinstance(value, bytes):
        return value.hex(" ") if value else "''"
    if isinstance(value, FirmwareVersion):
        return str(value)
    return repr(value) if isinstance(value, str) else str(value)


def describe(packet: Packet, direction: str) -> str:
    """One line of human text for a packet; ``direction`` is ``"request"`` (host to gripper) or ``"reply"``.

    Never raises: undecodable payloads are shown as hex with the reason.
    """
    is_request = direction.lower() in ("request", "tx", "send", "host->gripper", "out")
    arrow = "->" if is_request else "<-"
    name = command_name(packet.command)
    try:
        if is_request:
            values = decode_request(packet.command, packet.payload)
            text = " ".join(f"{k}={_format_value(v)}" for k, v in values.items())
            return f"{arrow} {name}" + (f" {text}" if text else "")
        reply = decode_reply(packet.command, packet.payload)
        text = " ".join(f"{k}={_format_value(v)}" for k, v in reply.fields.items())
        return f"{arrow} {name} {reply.status_name}" + (f" {text}" if text else "")
    except ProtocolError as exc:
        return f"{arrow} {name} [{exc.message}] {packet.payload.hex(' ')}"
