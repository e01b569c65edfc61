"""STEPFOC / Spectral CAN frames of the MSG gripper: identifiers, one command table, typed codecs.

Sans-IO: everything here maps (arbitration id, data bytes, remote flag) to typed values and back; the client,
the simulator and the CLI monitor all go through the same table (:data:`COMMANDS`), so a layout is written
once.

Byte order, bit order and the object-detection bits follow docs/protocols.md §2, which overrides the MSG
document (`seeds/004_…`): integers are big-endian, a flag byte's "bit 0" is its most significant bit (0x80),
and the status frame's detection value has its bit 0 at 0x20 and its bit 1 at 0x10.

A frame whose length does not fit its command raises :class:`FrameLengthError` (a :class:`ProtocolError`); it
is never padded or cut to fit.
"""

from __future__ import annotations

import struct
from collections.abc import Callable
from dataclasses import dataclass
from enum import Enum, IntEnum
from typing import Any, NamedTuple

from ..errors import LimitError, ProtocolError, URLError
from ..urls import parse_url, scheme_of, shown

__all__ = [
    "COMMANDS",
    "CanFrame",
    "Cmd",
    "parse_can_url",
    "CommandSpec",
    "DeviceInfo",
    "Detection",
    "Direction",
    "EncoderData",
    "ErrorState",
    "FrameLengthError",
    "GripperCommand",
    "GripperStatus",
    "Layout",
    "Message",
    "Watchdog",
    "WatchdogAction",
    "decode_command",
    "decode_frame",
    "decode_status",
    "describe",
    "encode_command",
    "encode_frame",
    "encode_status",
    "pack_id",
    "unpack_id",
]

MAX_NODE = 15  # 4 node bits: docs/protocols.md §2 / MSG document "Bits 10 - 7"
MAX_COMMAND = 63  # 6 command bits
DEFAULT_BITRATE = 1_000_000  # docs/protocols.md §2: 1 Mbit/s


class Cmd(IntEnum):
    """Command ids of the driver family that the gripper uses (docs/protocols.md §2 table, MSG document)."""

    ESTOP = 0
    CLEAR_ERROR = 1
    DATA_PACK_1 = 2  # motor mode, not used by the gripper; decoded as raw bytes
    DATA_PACK_1_REPLY = 3
    HEARTBEAT = 9
    PING = 10
    SET_CAN_ID = 11
    IDLE = 12
    SAVE_CONFIG = 13
    RESET = 14
    WATCHDOG = 15
    TEMPERATURE = 23
    BUS_VOLTAGE = 24
    DEVICE_INFO = 25
    ERROR_STATE = 26
    IQ = 27
    ENCODER = 28
    HEARTBEAT_SETUP = 30
    GRIPPER_STATUS = 60
    GRIPPER_COMMAND = 61
    GRIPPER_CALIBRATE = 62


class Direction(Enum):
    """Who sends a command's data frames. REMOTE: the host sends a remote frame, the node answers."""

    HOST_TO_NODE = "host->node"
    NODE_TO_HOST = "node->host"
    REMOTE = "remote request"


class Detection(IntEnum):
    """Object detection value of the status frame (docs/protocols.md §2; the vendor library swaps 1 and 2)."""

    MOVING = 0
    CLOSING_OBJECT = 1
    OPENING_OBJECT = 2
    AT_POSITION = 3


class WatchdogAction(IntEnum):
    """Watchdog action byte of command 15 (values as the vendor library `Spectral_BLDC` sends them)."""

    IDLE = 0
    HOLD = 1
    BRAKE = 2


class FrameLengthError(ProtocolError):
    """A frame whose data length does not fit its command; carries the command and both lengths."""

    def __init__(
        self, command: int, expected: tuple[int, ...], actual: int, *, device: str | None = None
    ) -> None:
        self.expected = expected
        self.actual = actual
        self.command_id = command
        want = " or ".join(str(n) for n in expected)
        super().__init__(
            f"{actual} data bytes, expected {want}", device=device, command=_command_name(command)
        )


# --------------------------------------------------------------------------------------------- identifiers


def pack_id(node: int, command: int, error: bool = False) -> int:
    """11-bit identifier ``node << 7 | command << 1 | error`` (docs/protocols.md §2)."""
    if not 0 <= node <= MAX_NODE:
        raise LimitError(f"node {node} outside 0..{MAX_NODE}")
    if not 0 <= command <= MAX_COMMAND:
        raise LimitError(f"command {command} outside 0..{MAX_COMMAND}")
    return node << 7 | command << 1 | (1 if error else 0)


# Every 11-bit identifier split once (2,048 tuples of cached small ints): one index per received frame.
_SPLIT_IDS: tuple[tuple[int, int, bool], ...] = tuple(
    (i >> 7, (i >> 1) & 0x3F, (i & 1) == 1) for i in range(0x800)
)


def unpack_id(arbitration_id: int) -> tuple[int, int, bool]:
    """(node, command, error bit) of an identifier; bits above the 11 standard ones are refused."""
    if not 0 <= arbitration_id <= 0x7FF:
        raise ProtocolError(f"identifier 0x{arbitration_id:X} is not a standard 11-bit identifier")
    return _SPLIT_IDS[arbitration_id]


# --------------------------------------------------------------------------------------------- typed values


# The three hot-path values below (GripperCommand, GripperStatus, Message) are slotted dataclasses WITHOUT
# frozen=True: a frozen dataclass routes every field of __init__ through object.__setattr__, which made
# building a GripperStatus ~5x slower than the whole vendor decode (benchmarks/, target 4). They keep value
# equality and hashing (unsafe_hash: computed from the fields) and are read-only by convention: the codecs
# never share an instance between callers, so nothing breaks if a caller does write to one.


@dataclass(slots=True, unsafe_hash=True)
class GripperCommand:
    """Command 61, host to gripper: position 0 (open) .. 255 (closed), speed byte, current limit in mA."""

    position: int
    speed: int
    current_ma: int
    activate: bool
    action: bool
    estop: bool
    release: bool = False  # "release direction", unused by the firmware (docs/protocols.md §2)


@dataclass(slots=True, unsafe_hash=True)
class GripperStatus:
    """Command 60, gripper to host. ``error_bit`` is the identifier's error bit (not a data bit)."""

    position: int
    current_ma: int
    activated: bool
    action: bool
    detection: Detection
    temperature_error: bool
    timeout_error: bool
    estop_error: bool
    calibrated: bool
    error_bit: bool = False


@dataclass(frozen=True, slots=True)
class DeviceInfo:
    """Reply to remote request 25: 7 bytes (docs/protocols.md §2)."""

    hardware_version: int
    batch_date: int
    software_version: int
    serial: int


@dataclass(frozen=True, slots=True)
class ErrorState:
    """Reply to remote request 26: two flag bytes, most significant bit first (docs/protocols.md §2)."""

    error: bool = False
    temperature: bool = False
    encoder: bool = False
    vbus: bool = False
    driver: bool = False
    velocity: bool = False
    current: bool = False
    estop: bool = False
    calibrated: bool = False
    activated: bool = False
    watchdog: bool = False

    def active(self) -> list[str]:
        """Names of the error flags that are set (for messages)."""
        names = ("temperature", "encoder", "vbus", "driver", "velocity", "current", "estop", "watchdog")
        return [n for n in names if getattr(self, n)]


@dataclass(frozen=True, slots=True)
class EncoderData:
    """Reply to remote request 28: encoder position (ticks) and velocity (ticks/s), i32 each."""

    position: int
    velocity: int


@dataclass(frozen=True, slots=True)
class Watchdog:
    """Command 15: time-out in ms (0 = off) and what the driver does when it fires."""

    timeout_ms: int
    action: WatchdogAction | int = WatchdogAction.IDLE


class CanFrame(NamedTuple):
    """A frame to put on the bus: what a transport needs and nothing more."""

    arbitration_id: int
    data: bytes = b""
    remote: bool = False


# --------------------------------------------------------------------------------------------- fast codecs

_COMMAND = struct.Struct(">BBhB")  # 61: position u8, speed u8, current i16, flags (docs/protocols.md §2)
_STATUS = struct.Struct(">BhB")  # 60: position u8, current i16, flags
_pack_command, _unpack_status = _COMMAND.pack, _STATUS.unpack  # bound once: these run for every frame
_new_object = object.__new__
_STATUS_ID = int(Cmd.GRIPPER_STATUS)  # plain ints: comparing with an IntEnum member costs a method call

# 61 flag bits; the document's "bit 0" is 0x80 (docs/protocols.md §2)
F_ACTIVATE, F_ACTION, F_ESTOP, F_RELEASE = 0x80, 0x40, 0x20, 0x10
# 60 flag bits
S_ACTIVATED, S_ACTION, S_DET_BIT0, S_DET_BIT1 = 0x80, 0x40, 0x20, 0x10
S_TEMPERATURE, S_TIMEOUT, S_ESTOP, S_CALIBRATED = 0x08, 0x04, 0x02, 0x01


def _status_flags(flags: int) -> tuple[bool, bool, Detection, bool, bool, bool, bool]:
    detection = Detection((1 if flags & S_DET_BIT0 else 0) | (2 if flags & S_DET_BIT1 else 0))
    return (
        bool(flags & S_ACTIVATED),
        bool(flags & S_ACTION),
        detection,
        bool(flags & S_TEMPERATURE),
        bool(flags & S_TIMEOUT),
        bool(flags & S_ESTOP),
        bool(flags & S_CALIBRATED),
    )


# every flag byte decoded once at import, with the identifier's error bit appended (index 0: clear, 1: set),
# so decode_status is one unpack, one index and the slot stores
_STATUS_FLAGS = tuple(_status_flags(f) for f in range(256))
_STATUS_TAIL = (
    tuple(flags + (False,) for flags in _STATUS_FLAGS),
    tuple(flags + (True,) for flags in _STATUS_FLAGS),
)
_DETECTION_FLAGS = (0, S_DET_BIT0, S_DET_BIT1, S_DET_BIT0 | S_DET_BIT1)
_COMMAND_FLAGS = tuple(
    (bool(f & F_ACTIVATE), bool(f & F_ACTION), bool(f & F_ESTOP), bool(f & F_RELEASE)) for f in range(256)
)


def encode_command(cmd: GripperCommand) -> bytes:
    """The 5 data bytes of command 61. Out-of-range values raise LimitError (nothing is clamped here)."""
    flags = (
        (F_ACTIVATE if cmd.activate else 0)
        | (F_ACTION if cmd.action else 0)
        | (F_ESTOP if cmd.estop else 0)
        | (F_RELEASE if cmd.release else 0)
    )
    try:
        return _pack_command(cmd.position, cmd.speed, cmd.current_ma, flags)
    except struct.error:
        raise LimitError(
            f"position {cmd.position!r} / speed {cmd.speed!r} must be 0..255 and current "
            f"{cmd.current_ma!r} mA -32768..32767",
            command="GRIPPER_COMMAND",
        ) from None


def decode_command(data: bytes) -> GripperCommand:
    """Command 61 data (5 bytes). The low four flag bits are reserved and ignored."""
    if len(data) != 5:
        raise FrameLengthError(Cmd.GRIPPER_COMMAND, (5,), len(data))
    position, speed, current, flags = _COMMAND.unpack(data)
    return GripperCommand(position, speed, current, *_COMMAND_FLAGS[flags])


def encode_status(st: GripperStatus) -> bytes:
    """The 4 data bytes of command 60 (the error bit belongs to the identifier, not here)."""
    flags = (
        (S_ACTIVATED if st.activated else 0)
        | (S_ACTION if st.action else 0)
        | _DETECTION_FLAGS[st.detection & 3]
        | (S_TEMPERATURE if st.temperature_error else 0)
        | (S_TIMEOUT if st.timeout_error else 0)
        | (S_ESTOP if st.estop_error else 0)
        | (S_CALIBRATED if st.calibrated else 0)
    )
    try:
        return _STATUS.pack(st.position, st.current_ma, flags)
    except struct.error:
        raise LimitError(
            f"position {st.position!r} must be 0..255 and current {st.current_ma!r} mA -32768..32767",
            command="GRIPPER_STATUS",
        ) from None


def decode_status(data: bytes | bytearray, error_bit: bool = False) -> GripperStatus:
    """Command 60 data (4 bytes); ``error_bit`` comes from the frame's identifier.

    No memoisation: building a status is cheap (see the note above GripperCommand), and during a motion
    nearly every frame differs, so a cache would mostly cost a lookup and hold on to memory.
    """
    try:
        position, current, flags = _unpack_status(data)
    except struct.error:
        raise FrameLengthError(Cmd.GRIPPER_STATUS, (4,), len(data)) from None
    # Filled slot by slot instead of through __init__: saves the *args tuple and a second Python frame,
    # a quarter of the decode time. Every field of GripperStatus is set here (the tests compare whole values).
    st = _new_object(GripperStatus)
    st.position = position
    st.current_ma = current
    (
        st.activated,
        st.action,
        st.detection,
        st.temperature_error,
        st.timeout_error,
        st.estop_error,
        st.calibrated,
        st.error_bit,
    ) = _STATUS_TAIL[1 if error_bit else 0][flags]
    return st


def _encode_error_state(es: ErrorState) -> bytes:
    b0 = (
        (0x80 if es.error else 0)
        | (0x40 if es.temperature else 0)
        | (0x20 if es.encoder else 0)
        | (0x10 if es.vbus else 0)
        | (0x08 if es.driver else 0)
        | (0x04 if es.velocity else 0)
        | (0x02 if es.current else 0)
        | (0x01 if es.estop else 0)
    )
    b1 = (0x80 if es.calibrated else 0) | (0x40 if es.activated else 0) | (0x20 if es.watchdog else 0)
    return bytes((b0, b1))


def _decode_error_state(data: bytes) -> ErrorState:
    b0, b1 = data[0], data[1]
    names = ("error", "temperature", "encoder", "vbus", "driver", "velocity", "current", "estop")
    flags = {n: bool(b0 & (0x80 >> i)) for i, n in enumerate(names)}
    return ErrorState(
        **flags, calibrated=bool(b1 & 0x80), activated=bool(b1 & 0x40), watchdog=bool(b1 & 0x20)
    )


# --------------------------------------------------------------------------------------------- the table


@dataclass(frozen=True, slots=True)
class Layout:
    """One data layout: its length, how to build and read it, and a one-line rendering for the monitor."""

    length: int
    encode: Callable[[Any], bytes]
    decode: Callable[[bytes], Any]
    text: Callable[[Any], str]


def _empty_layout() -> Layout:
    return Layout(0, lambda _v: b"", lambda _d: None, lambda _v: "")


def _scalar(fmt: str, unit: str, label: str, valid: tuple[int, int] | None = None) -> Layout:
    """``valid``: the physically possible values; a reply outside them is a ProtocolError, not a reading."""
    s = struct.Struct(fmt)

    def dec(d: bytes) -> int:
        value = s.unpack(d)[0]
        if valid is not None and not valid[0] <= value <= valid[1]:
            raise ProtocolError(f"{label} {value}{unit} outside {valid[0]}..{valid[1]}{unit}")
        return value

    def enc(v: int) -> bytes:
        try:
            return s.pack(v)
        except struct.error:
            raise LimitError(f"{label} {v!r} does not fit {fmt!r}") from None

    return Layout(s.size, enc, dec, lambda v: f"{label}={v}{unit}")


def _record(fmt: str, cls: Any, label: str, convert: Callable[[Any], tuple] | None = None) -> Layout:
    s = struct.Struct(fmt)  # cls: a dataclass (its fields, in order, are the record's)

    def enc(v: Any) -> bytes:
        values = convert(v) if convert else tuple(getattr(v, f) for f in cls.__dataclass_fields__)
        try:
            return s.pack(*values)
        except struct.error:
            raise LimitError(f"{label} {v!r} does not fit {fmt!r}") from None

    def text(v: Any) -> str:
        return " ".join(f"{k}={getattr(v, k)}" for k in cls.__dataclass_fields__)

    return Layout(s.size, enc, lambda d: cls(*s.unpack(d)), text)


def _status_text(st: GripperStatus) -> str:
    flags = [
        n
        for n in ("activated", "action", "temperature_error", "timeout_error", "estop_error", "calibrated")
        if getattr(st, n)
    ]
    return f"pos={st.position} current={st.current_ma}mA det={st.detection.name} " + ",".join(flags)


def _command_text(c: GripperCommand) -> str:
    flags = [n for n in ("activate", "action", "estop", "release") if getattr(c, n)]
    return f"pos={c.position} speed={c.speed} current={c.current_ma}mA " + ",".join(flags)


_STATUS_LAYOUT = Layout(4, encode_status, decode_status, _status_text)
_COMMAND_LAYOUT = Layout(5, encode_command, decode_command, _command_text)
_ERROR_STATE_LAYOUT = Layout(
    2,
    _encode_error_state,
    _decode_error_state,
    lambda e: "flags=" + ",".join([n for n in ErrorState.__dataclass_fields__ if getattr(e, n)]),
)


def _watchdog_decode(d: bytes) -> Watchdog:
    ms, action = struct.unpack(">IB", d)
    try:
        return Watchdog(ms, WatchdogAction(action))
    except ValueError:
        return Watchdog(
            ms, action
        )  # an unknown action byte kept as a plain int (the firmware never reads it)


_WATCHDOG_LAYOUT = Layout(
    5,
    _record(">IB", Watchdog, "watchdog").encode,
    _watchdog_decode,
    lambda w: f"timeout={w.timeout_ms}ms action={getattr(w.action, 'name', w.action)}",
)


def _raw_layouts() -> tuple[Layout, ...]:
    # motor-mode frames the gripper does not use: shown as hex, any length accepted
    return tuple(Layout(n, bytes, bytes, lambda v: v.hex(" ")) for n in range(9))


@dataclass(frozen=True, slots=True)
class CommandSpec:
    """One row of the command table. ``layouts``: accepted data-frame layouts (for REMOTE: the reply)."""

    cmd: Cmd
    name: str
    direction: Direction
    layouts: tuple[Layout, ...]
    doc: str

    @property
    def remote(self) -> bool:
        return self.direction is Direction.REMOTE

    @property
    def lengths(self) -> tuple[int, ...]:
        return tuple(lay.length for lay in self.layouts)

    def layout_for(self, length: int) -> Layout:
        for lay in self.layouts:
            if lay.length == length:
                return lay
        raise FrameLengthError(self.cmd, self.lengths, length)


_E = _empty_layout()
_TEMPERATURE = _scalar(">h", "C", "temperature", (-273, 32767))  # below absolute zero is no reading
_VOLTAGE = _scalar(">h", "mV", "voltage", (0, 32767))  # a supply voltage is not negative
_H, _N, _R = Direction.HOST_TO_NODE, Direction.NODE_TO_HOST, Direction.REMOTE

# docs/protocols.md §2 (table and the 60/61 layouts); MSG document for 60, 61, 62, 11, 13, 14, 1
COMMANDS: dict[int, CommandSpec] = {
    s.cmd: s
    for s in (
        CommandSpec(Cmd.ESTOP, "estop", _H, (_E,), "e-stop, no reply"),
        CommandSpec(Cmd.CLEAR_ERROR, "clear_error", _H, (_E,), "clear errors, no reply"),
        CommandSpec(Cmd.DATA_PACK_1, "data_pack_1", _H, _raw_layouts(), "motor mode, unused by the gripper"),
        CommandSpec(Cmd.DATA_PACK_1_REPLY, "data_pack_1_reply", _N, _raw_layouts(), "motor mode reply"),
        CommandSpec(Cmd.HEARTBEAT, "heartbeat", _N, (_E,), "sent periodically once set up by 30"),
        CommandSpec(Cmd.PING, "ping", _R, (_E,), "remote request; the reply has no data"),
        CommandSpec(Cmd.SET_CAN_ID, "set_can_id", _H, (_scalar(">B", "", "new_node"),), "no reply"),
        CommandSpec(Cmd.IDLE, "idle", _H, (_E,), "motor idle, no reply"),
        CommandSpec(Cmd.SAVE_CONFIG, "save_config", _H, (_E,), "no reply"),
        CommandSpec(Cmd.RESET, "reset", _H, (_E,), "reboot, no reply"),
        CommandSpec(Cmd.WATCHDOG, "watchdog", _H, (_WATCHDOG_LAYOUT,), "u32 ms + action byte"),
        CommandSpec(Cmd.TEMPERATURE, "temperature", _R, (_TEMPERATURE,), "i16 degC"),
        CommandSpec(Cmd.BUS_VOLTAGE, "bus_voltage", _R, (_VOLTAGE,), "i16 mV"),
        CommandSpec(
            Cmd.DEVICE_INFO,
            "device_info",
            _R,
            (_record(">BBBi", DeviceInfo, "device_info"),),
            "hw u8, batch u8, sw u8, serial i32",
        ),
        CommandSpec(Cmd.ERROR_STATE, "error_state", _R, (_ERROR_STATE_LAYOUT,), "2 flag bytes"),
        CommandSpec(Cmd.IQ, "iq", _R, (_scalar(">h", "mA", "iq"),), "i16 mA"),
        CommandSpec(
            Cmd.ENCODER, "encoder", _R, (_record(">ii", EncoderData, "encoder"),), "i32 ticks, i32 ticks/s"
        ),
        CommandSpec(
            Cmd.HEARTBEAT_SETUP, "heartbeat_setup", _H, (_scalar(">I", "ms", "period"),), "u32 ms, 0 off"
        ),
        CommandSpec(Cmd.GRIPPER_STATUS, "gripper_status", _N, (_STATUS_LAYOUT,), "answer to every 61"),
        CommandSpec(
            Cmd.GRIPPER_COMMAND,
            "gripper_command",
            _H,
            (_E, _COMMAND_LAYOUT),
            "5 bytes = command, 0 bytes = poll; any length answered by 60",
        ),
        CommandSpec(Cmd.GRIPPER_CALIBRATE, "gripper_calibrate", _H, (_E,), "no reply"),
    )
}


_STATUS_SPEC = COMMANDS[Cmd.GRIPPER_STATUS]


def _command_name(command: int) -> str:
    spec = COMMANDS.get(command)
    return spec.name if spec else f"command {command}"


# --------------------------------------------------------------------------------------------- whole frames


@dataclass(slots=True, unsafe_hash=True)
class Message:
    """A decoded frame. ``value``: the typed payload (None for empty frames and remote requests)."""

    node: int
    command: int
    error: bool
    remote: bool
    data: bytes
    value: Any
    spec: CommandSpec | None

    @property
    def name(self) -> str:
        return self.spec.name if self.spec else f"command_{self.command}"

    @property
    def from_node(self) -> bool:
        """True for frames a node sends (status, heartbeat, replies to remote requests)."""
        if self.spec is None or self.remote:
            return False
        return self.spec.direction in (Direction.NODE_TO_HOST, Direction.REMOTE)

    def describe(self) -> str:
        err = " ERR" if self.error else ""
        if self.remote:
            body = "request"
        elif self.spec is None:
            body = self.data.hex(" ")
        else:
            body = self.spec.layout_for(len(self.data)).text(self.value)
            if self.cmd_is(Cmd.GRIPPER_COMMAND) and not self.data:
                body = "poll"
        kind = " (remote)" if self.remote else ""
        return f"node {self.node} {self.name}{kind}{err} {body}".rstrip()

    def cmd_is(self, cmd: Cmd) -> bool:
        return self.command == cmd


def decode_frame(arbitration_id: int, data: bytes | bytearray, is_remote: bool = False) -> Message:
    """Decode one frame. Unknown command ids decode to raw bytes; a wrong length raises FrameLengthError."""
    if not 0 <= arbitration_id <= 0x7FF:
        unpack_id(arbitration_id)  # raises, with the one wording for this error
    node, command, error = _SPLIT_IDS[arbitration_id]  # unpack_id's table, without its call
    data = bytes(data)
    if command == _STATUS_ID and not is_remote:  # the frame a polling client receives most
        return Message(node, command, error, False, data, decode_status(data, error), _STATUS_SPEC)
    spec = COMMANDS.get(command)
    if spec is None:
        return Message(node, command, error, is_remote, data, data, None)
    if is_remote:
        if not spec.remote:
            raise ProtocolError("remote frame for a command that takes data frames", command=spec.name)
        return Message(node, command, error, True, b"", None, spec)
    return Message(node, command, error, False, data, spec.layout_for(len(data)).decode(data), spec)


def encode_frame(
    node: int, command: int, value: Any = None, *, remote: bool = False, error: bool = False
) -> CanFrame:
    """Build a frame from the table. For a REMOTE command, ``remote=True`` builds the request, otherwise the
    reply; for 61, ``value=None`` builds the empty poll."""
    spec = COMMANDS.get(command)
    arbitration_id = pack_id(node, command, error)
    if spec is None:
        return CanFrame(arbitration_id, bytes(value or b""), remote)
    if remote:
        if not spec.remote:
            raise ProtocolError("this command is not a remote request", command=spec.name)
        return CanFrame(arbitration_id, b"", True)
    if value is None:
        layout = spec.layout_for(0)
    else:
        nonempty = [lay for lay in spec.layouts if lay.length]
        if not nonempty:
            raise ProtocolError(f"takes no data, got {value!r}", command=spec.name)
        layout = (
            nonempty[0]
            if spec.cmd not in (Cmd.DATA_PACK_1, Cmd.DATA_PACK_1_REPLY)
            else spec.layout_for(len(value))
        )
    return CanFrame(arbitration_id, layout.encode(value), False)


def describe(arbitration_id: int, data: bytes | bytearray, is_remote: bool = False) -> str:
    """One line for the monitor; never raises (bad frames are shown with the reason)."""
    try:
        return decode_frame(arbitration_id, data, is_remote).describe()
    except FrameLengthError as exc:
        node, command, error = unpack_id(arbitration_id)
        err = " ERR" if error else ""
        return f"node {node} {_command_name(command)}{err} BAD LENGTH {bytes(data).hex(' ')} ({exc.message})"
    except ProtocolError as exc:
        return f"0x{arbitration_id:03X} {bytes(data).hex(' ')} ({exc})"


def parse_can_url(listen: str) -> tuple[str, str, dict[str, str]]:
    """``[stepfoc+]can://INTERFACE/CHANNEL?k=v`` -> (interface, channel, query), by the one URL grammar
    (``drivers/urls.py``: everything after the first ``/`` is the channel, so a multicast channel may be an
    IPv6 address full of colons). A malformed URL is a URLError (also a ValueError)."""
    if scheme_of(listen) not in ("can", "stepfoc+can"):
        raise URLError(f"not a CAN URL: {shown(listen)} (expected can://INTERFACE/CHANNEL)")
    url = parse_url(listen, bare_family="stepfoc")
    assert url.interface and url.channel  # the grammar refuses a CAN URL without them
    return url.interface, url.channel, url.params
