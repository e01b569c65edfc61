"""SCHUNK EGU / EGK / EZU process data and parameters, sans-IO: bytes in, values out, and back.

Every fact here is from SCHUNK's published driver and dummy (GitHub
SCHUNK-SE-Co-KG/schunk_mechatronic_gripper, GPL-3.0; facts only, no code): docs/protocols-schunk.md names
the file each one comes from. Both transports carry the same bytes: the web API as upper-case hex
(``["0B"]``), Modbus RTU as registers of two bytes each in that same order. So one codec serves the HTTP
client, the RTU client and the simulator.

The byte order is the fieldbus's: EtherNet/IP, EtherCAT and Modbus are little-endian, PROFINET is big-endian
for floats and 16/32-bit integers; an enum's value sits in its first byte; status and control bit ``n`` is in
byte ``n // 8`` on every fieldbus.
"""

from __future__ import annotations

import enum
import struct
from dataclasses import dataclass

PLC_INPUT = 0x0040  # process data from the unit: status, position, reserved, diagnostics (16 bytes)
PLC_OUTPUT = 0x0048  # process data to the unit: control, target position, target speed, force (16 bytes)
PROCESS_DATA_BYTES = 16
ERROR_BYTE, WARNING_BYTE, ADDITIONAL_BYTE = 12, 14, 15  # in 0x0040, little-endian fieldbuses
DEFAULT_HTTP_PORT = 80
DEFAULT_DEVICE_ID = 12  # Modbus slave id SCHUNK's driver and tests use
MODBUS_BAUDRATE = 115200  # 8 data bits, even parity, 1 stop bit
TOGGLE_TIMEOUT_S = 0.1  # SCHUNK's driver gives a move or grip this long to toggle "command received"


class Fieldbus(enum.IntEnum):
    """Parameter 0x1130, fieldbus_type (library config/fieldbus_types.json)."""

    PROFINET = 1
    ETHERNET_IP = 2
    ETHERCAT = 3
    MODBUS = 7

    @property
    def big_endian(self) -> bool:
        return self is Fieldbus.PROFINET

    @property
    def short(self) -> str:
        return {1: "PN", 2: "EI", 3: "EC", 7: "MB"}[self.value]


class Status(enum.IntFlag):
    """The status double word of 0x0040 (bits as SCHUNK's driver and dummy name them)."""

    READY = 1 << 0  # ready for operation
    NOT_FEASIBLE = 1 << 3  # command not feasible
    SUCCESS = 1 << 4  # command successfully processed
    RECEIVED = 1 << 5  # command received: toggles with each command
    ERROR = 1 << 7
    NO_WORKPIECE = 1 << 11
    GRIPPED = 1 << 12  # workpiece gripped
    REACHED = 1 << 13  # position reached
    WRONG_WORKPIECE = 1 << 17
    GPE = 1 << 31  # grip force and position maintenance active


OUTCOME_BITS = (
    Status.NOT_FEASIBLE
    | Status.SUCCESS
    | Status.NO_WORKPIECE
    | Status.GRIPPED
    | Status.REACHED
    | Status.WRONG_WORKPIECE
)


class Control(enum.IntFlag):
    """The control double word of 0x0048. ``FAST_STOP_OFF`` (bit 0) is active low: every command word
    carries it set; a word with only it set is no command; a word with it clear is a fast stop."""

    FAST_STOP_OFF = 1 << 0
    STOP = 1 << 1
    ACKNOWLEDGE = 1 << 2
    PREPARE_SHUTDOWN = 1 << 3
    OUTWARD = 1 << 7  # grip outward
    RELEASE = 1 << 11  # release workpiece
    GRIP = 1 << 12
    MOVE_ABSOLUTE = 1 << 13
    MOVE_RELATIVE = 1 << 14
    GRIP_AT_POSITION = 1 << 16
    BRAKE_TEST = 1 << 30
    GPE = 1 << 31


NO_COMMAND = Control.FAST_STOP_OFF
ERR_FAST_STOP = 0xD9

# Error codes with the names SCHUNK's repository gives them. Its sources name one (0xD9, ERR_FAST_STOP, in
# the dummy's tests); the unit lists the rest itself (GET /adi/enum.json?inst=280, the dummy's config README),
# so any other code is reported by its number.
ERROR_NAMES: dict[int, str] = {ERR_FAST_STOP: "ERR_FAST_STOP"}


def error_name(code: int) -> str:
    return ERROR_NAMES.get(code, f"error 0x{code:02X}")


class Kind(enum.Enum):
    ENUM = "enum"
    FLOAT = "float"
    UINT16 = "uint16"
    UINT32 = "uint32"
    TEXT = "char"
    BOOL = "bool"
    BYTES = "bytes"  # arrays (float[6], uint8[6]): carried as they are, decoded as upper-case hex
    RAW = "raw"  # the process data: decoded by ProcessInput / ControlWord


@dataclass(frozen=True)
class Parameter:
    inst: int
    name: str
    registers: int  # Modbus registers of two bytes (the web API carries the same bytes)
    kind: Kind
    writable: bool = False
    unit: str = ""

    @property
    def size(self) -> int:
        return 2 * self.registers


def _table(*rows: Parameter) -> dict[int, Parameter]:
    return {p.inst: p for p in rows}


P = Parameter
# The parameters the library reads or writes (library config/readable_parameters.json and
# writable_parameters.json: instance, name, register count, type).
PARAMETERS: dict[int, Parameter] = _table(
    P(PLC_INPUT, "plc_sync_input", 8, Kind.RAW),
    P(PLC_OUTPUT, "plc_sync_output", 8, Kind.RAW, writable=True),
    P(0x0118, "err_code", 1, Kind.ENUM),
    P(0x0120, "wrn_code", 1, Kind.ENUM),
    P(0x0128, "sys_msg_req", 1, Kind.UINT16, writable=True),
    P(0x0130, "sys_msg_buffer", 107, Kind.TEXT),
    P(0x0230, "actual_pos", 2, Kind.FLOAT, unit="mm"),
    P(0x0238, "actual_vel", 2, Kind.FLOAT, unit="mm/s"),
    P(0x0380, "grp_prehold_time", 1, Kind.UINT16, writable=True, unit="ms"),
    P(0x03A8, "dead_load_kg", 2, Kind.FLOAT, unit="kg"),
    P(0x03B0, "tool_cent_point", 12, Kind.BYTES),
    P(0x03B8, "cent_of_mass", 12, Kind.BYTES),
    P(0x0500, "module_type", 1, Kind.ENUM),
    P(0x0528, "wp_lost_dst", 2, Kind.FLOAT, writable=True, unit="mm"),
    P(0x0540, "wp_release_delta", 2, Kind.FLOAT, writable=True, unit="mm"),
    P(0x0580, "grp_pos_margin", 2, Kind.FLOAT, writable=True, unit="mm"),
    P(0x0588, "max_phys_stroke", 2, Kind.FLOAT, unit="mm"),
    P(0x05A8, "grp_prepos_delta", 2, Kind.FLOAT, writable=True, unit="mm"),
    P(0x0600, "min_pos", 2, Kind.FLOAT, writable=True, unit="mm"),
    P(0x0608, "max_pos", 2, Kind.FLOAT, writable=True, unit="mm"),
    P(0x0610, "zero_pos_ofs", 2, Kind.FLOAT, writable=True, unit="mm"),
    P(0x0628, "min_vel", 2, Kind.FLOAT, unit="mm/s"),
    P(0x0630, "max_vel", 2, Kind.FLOAT, unit="mm/s"),
    P(0x0650, "max_grp_vel", 2, Kind.FLOAT, unit="mm/s"),
    P(0x0658, "min_grp_force", 2, Kind.FLOAT, unit="N"),
    P(0x0660, "max_grp_force", 2, Kind.FLOAT, unit="N"),
    P(0x06A8, "max_allow_force", 2, Kind.FLOAT, unit="N"),
    P(0x0800, "min_err_mot_volt", 2, Kind.FLOAT, unit="V"),
    P(0x0808, "max_err_mot_volt", 2, Kind.FLOAT, unit="V"),
    P(0x0810, "min_err_lgc_volt", 2, Kind.FLOAT, unit="V"),
    P(0x0818, "max_err_lgc_volt", 2, Kind.FLOAT, unit="V"),
    P(0x0820, "min_err_lgc_temp", 2, Kind.FLOAT, unit="°C"),
    P(0x0828, "max_err_lgc_temp", 2, Kind.FLOAT, unit="°C"),
    P(0x0840, "meas_lgc_temp", 2, Kind.FLOAT, unit="°C"),
    P(0x0870, "meas_lgc_volt", 2, Kind.FLOAT, unit="V"),
    P(0x0878, "meas_mot_volt", 2, Kind.FLOAT, unit="V"),
    P(0x0880, "min_wrn_mot_volt", 2, Kind.FLOAT, writable=True, unit="V"),
    P(0x0888, "max_wrn_mot_volt", 2, Kind.FLOAT, writable=True, unit="V"),
    P(0x0890, "min_wrn_lgc_volt", 2, Kind.FLOAT, writable=True, unit="V"),
    P(0x0898, "max_wrn_lgc_volt", 2, Kind.FLOAT, writable=True, unit="V"),
    P(0x08A0, "min_wrn_lgc_temp", 2, Kind.FLOAT, unit="°C"),
    P(0x08A8, "max_wrn_lgc_temp", 2, Kind.FLOAT, unit="°C"),
    P(0x1000, "serial_no_txt", 8, Kind.TEXT),
    P(0x1008, "order_no_txt", 8, Kind.TEXT),
    P(0x1020, "serial_no_num", 2, Kind.UINT32),
    P(0x1100, "sw_build_date", 6, Kind.TEXT),
    P(0x1108, "sw_build_time", 5, Kind.TEXT),
    P(0x1110, "sw_version_num", 1, Kind.UINT16),
    P(0x1118, "sw_version_txt", 11, Kind.TEXT),
    P(0x1130, "fieldbus_type", 1, Kind.ENUM),
    P(0x1138, "mac_addr", 3, Kind.BYTES),  # Ethernet units only
    P(0x11A0, "baudrate", 2, Kind.UINT32, writable=True),  # Modbus units only
    P(
        0x11A8, "slave_id", 1, Kind.ENUM, writable=True
    ),  # Modbus units only; a uint8, in the first byte as an enum's
    P(0x1330, "enable_softreset", 1, Kind.BOOL, writable=True),
    P(0x1400, "system_uptime", 2, Kind.UINT32, unit="s"),
)
BY_NAME: dict[str, Parameter] = {p.name: p for p in PARAMETERS.values()}

# What SCHUNK's driver reads at connect (update_module_parameters): connect fails if one is missing.
CONNECT_PARAMETERS = (
    "fieldbus_type",
    "module_type",
    "wp_release_delta",
    "max_phys_stroke",
    "min_pos",
    "max_pos",
    "max_vel",
    "max_grp_vel",
    "max_grp_force",
    "serial_no_txt",
    "sw_version_txt",
)
# Read too when present (the list), never required.
OPTIONAL_PARAMETERS = ("min_vel", "min_grp_force", "max_allow_force", "serial_no_num", "sw_version_num")

# Parameter 0x0500, module_type (library config/module_types.json); N/M: without/with GPE, B/SD: variants.
MODULE_TYPES: dict[int, str] = {
    6: "EGU_50_N_B", 7: "EGU_60_N_B", 8: "EGU_70_N_B", 9: "EGU_80_N_B",
    10: "EGU_50_M_B", 11: "EGU_60_M_B", 12: "EGU_70_M_B", 13: "EGU_80_M_B",
    14: "EGK_25_N_B", 15: "EGK_40_N_B", 16: "EGK_50_N_B",
    17: "EGK_25_M_B", 18: "EGK_40_M_B", 19: "EGK_50_M_B",
    20: "EGU_50_N_SD", 21: "EGU_60_N_SD", 22: "EGU_70_N_SD", 23: "EGU_80_N_SD",
    24: "EGU_50_M_SD", 25: "EGU_60_M_SD", 26: "EGU_70_M_SD", 27: "EGU_80_M_SD",
    28: "EZU_30_N_B", 29: "EZU_35_N_B", 30: "EZU_40_N_B",
    31: "EZU_30_M_B", 32: "EZU_35_M_B", 33: "EZU_40_M_B",
    34: "EZU_30_N_SD", 35: "EZU_35_N_SD", 36: "EZU_40_N_SD",
    37: "EZU_30_M_SD", 38: "EZU_35_M_SD", 39: "EZU_40_M_SD",
}  # fmt: skip


def has_gpe(module_type: str) -> bool:
    """An "M" module keeps grip force and position (GPE); SCHUNK's driver sends bit 31 only to those."""
    parts = module_type.split("_")
    return len(parts) >= 3 and parts[2] == "M"


def profile_name(module_type: str) -> str | None:
    """``EGU_60_M_B`` -> ``schunk-egu-60``: the profile of the module's size."""
    parts = module_type.split("_")
    if len(parts) < 2 or not parts[1].isdigit():
        return None
    return f"schunk-{parts[0].lower()}-{parts[1]}"


class CodecError(ValueError):
    """Bytes that are not the parameter's layout (a short reply, non-hex text, a text that is not ASCII)."""


def parameter(inst: int) -> Parameter:
    try:
        return PARAMETERS[inst]
    except KeyError:
        raise CodecError(f"unknown parameter 0x{inst:04X}") from None


def inst_text(inst: int) -> str:
    """``0x0040``: how the web API writes an instance (SCHUNK's dummy matches it as text)."""
    return f"0x{inst:04X}"


def padded(inst: int, data: bytes) -> bytes:
    """The parameter's bytes at full size: the web API sends an enum as one byte (``["0B"]``) where Modbus
    sends its register of two; SCHUNK's driver pads short replies with zeros. Longer than the layout is an
    error."""
    size = parameter(inst).size
    if len(data) > size:
        raise CodecError(f"0x{inst:04X}: {len(data)} bytes, the parameter has {size}")
    return bytes(data) + bytes(size - len(data))


def _order(fieldbus: Fieldbus) -> str:
    return ">" if fieldbus.big_endian else "<"


def decode(inst: int, data: bytes, fieldbus: Fieldbus) -> float | int | str | bool:
    """One parameter's value from its bytes, in the fieldbus's byte order."""
    p = parameter(inst)
    data = padded(inst, data)
    o = _order(fieldbus)
    if p.kind is Kind.ENUM:
        return data[0]
    if p.kind is Kind.BOOL:
        return bool(data[0])
    if p.kind is Kind.FLOAT:
        return float(struct.unpack(o + "f", data[:4])[0])
    if p.kind is Kind.UINT16:
        return int(struct.unpack(o + "H", data[:2])[0])
    if p.kind is Kind.UINT32:
        return int(struct.unpack(o + "I", data[:4])[0])
    if p.kind is Kind.TEXT:
        try:
            return data.decode("ascii").strip(" \x00")
        except UnicodeDecodeError:
            raise CodecError(f"0x{inst:04X}: a text that is not ASCII") from None
    if p.kind is Kind.BYTES:
        return data.hex().upper()
    raise CodecError(f"0x{inst:04X} is process data: use ProcessInput/ControlWord")


def encode(inst: int, value: float | int | str | bool, fieldbus: Fieldbus) -> bytes:
    """A parameter's bytes for ``value`` (what the simulator serves and what a write sends)."""
    p = parameter(inst)
    o = _order(fieldbus)
    try:
        if p.kind in (Kind.ENUM, Kind.BOOL):
            data = struct.pack("B", int(value))
        elif p.kind is Kind.FLOAT:
            data = struct.pack(o + "f", float(value))
        elif p.kind is Kind.UINT16:
            data = struct.pack(o + "H", int(value))
        elif p.kind is Kind.UINT32:
            data = struct.pack(o + "I", int(value))
        elif p.kind is Kind.TEXT:
            data = str(value).encode("ascii")
        elif p.kind is Kind.BYTES:
            data = bytes.fromhex(str(value))
        else:
            raise CodecError(f"0x{inst:04X} is process data")
    except (struct.error, UnicodeEncodeError, ValueError, OverflowError) as exc:
        raise CodecError(f"0x{inst:04X}: cannot encode {value!r} ({exc})") from None
    return padded(inst, data)


def from_hex(text: str) -> bytes:
    try:
        return bytes.fromhex(text)
    except ValueError:
        raise CodecError(f"not hex: {text[:40]!r}") from None


@dataclass(frozen=True)
class ProcessInput:
    """0x0040 decoded: the status bits, the actual position (µm) and the diagnostics."""

    status: Status
    position_um: int
    error: int
    warning: int
    additional: int

    @classmethod
    def decode(cls, data: bytes, fieldbus: Fieldbus) -> ProcessInput:
        if len(data) != PROCESS_DATA_BYTES:
            raise CodecError(f"0x0040: {len(data)} bytes, not {PROCESS_DATA_BYTES}")
        (position,) = struct.unpack(_order(fieldbus) + "i", data[4:8])
        # The diagnostics double word in the fieldbus's order: its low byte is the error code (byte 12 on
        # the little-endian fieldbuses, byte 15 on PROFINET: the dummy's EGU_60_PN_M_B.json).
        diag = data[12:16] if not fieldbus.big_endian else data[12:16][::-1]
        return cls(Status(int.from_bytes(data[0:4], "little")), position, diag[0], diag[2], diag[3])

    def encode(self, fieldbus: Fieldbus) -> bytes:
        diag = bytes((self.error, 0, self.warning, self.additional))
        if fieldbus.big_endian:
            diag = diag[::-1]
        return (
            int(self.status).to_bytes(4, "little")
            + struct.pack(_order(fieldbus) + "i", self.position_um)
            + bytes(4)
            + diag
        )

    def has(self, flag: Status) -> bool:
        return bool(self.status & flag)


@dataclass(frozen=True)
class ControlWord:
    """0x0048: the control bits, target position (µm), target speed (µm/s) and force (% of the maximum)."""

    control: Control = NO_COMMAND
    position_um: int = 0
    speed_um_s: int = 0
    force_percent: int = 0

    def encode(self, fieldbus: Fieldbus) -> bytes:
        o = _order(fieldbus)
        try:
            return int(self.control).to_bytes(4, "little") + struct.pack(
                o + "iiI", self.position_um, self.speed_um_s, self.force_percent
            )
        except struct.error as exc:
            raise CodecError(f"0x0048: a value out of range ({exc})") from None

    @classmethod
    def decode(cls, data: bytes, fieldbus: Fieldbus) -> ControlWord:
        if len(data) != PROCESS_DATA_BYTES:
            raise CodecError(f"0x0048: {len(data)} bytes, not {PROCESS_DATA_BYTES}")
        position, speed, force = struct.unpack(_order(fieldbus) + "iiI", data[4:16])
        return cls(Control(int.from_bytes(data[0:4], "little")), position, speed, force)

    @property
    def is_command(self) -> bool:
        """Only bit 0 set is no command; everything else (bit 0 clear: a fast stop) is one."""
        return self.control != NO_COMMAND


class Outcome(enum.Enum):
    PENDING = "pending"
    DONE = "done"  # position reached / processed
    GRIPPED = "gripped"
    NO_WORKPIECE = "no workpiece detected"
    WRONG_WORKPIECE = "wrong workpiece"
    BLOCKED = "processed short of its target"
    NOT_FEASIBLE = "command not feasible"
    ERROR = "error"


@dataclass(frozen=True)
class CommandTracker:
    """The command-received toggle as pure state: a command is answered once bit 5 differs from what it
    was before the command went out, and only then do the outcome bits belong to it (bits left from the
    previous command never end this one). ``kind``: what the command waits for."""

    before: bool  # bit 5 read before the command was sent
    kind: str  # "move", "grip", "release", "stop", "acknowledge", "fast_stop"

    @classmethod
    def after(cls, reading: ProcessInput, kind: str) -> CommandTracker:
        return cls(reading.has(Status.RECEIVED), kind)

    def received(self, reading: ProcessInput) -> bool:
        return reading.has(Status.RECEIVED) != self.before

    def outcome(self, reading: ProcessInput) -> Outcome:
        if not self.received(reading):
            return Outcome.PENDING
        s = reading.status
        if self.kind == "fast_stop":
            return Outcome.DONE if s & Status.ERROR else Outcome.PENDING
        if s & Status.ERROR:
            return Outcome.ERROR
        if self.kind == "acknowledge":
            return Outcome.DONE if s & Status.READY else Outcome.PENDING
        if s & Status.NOT_FEASIBLE:
            return Outcome.NOT_FEASIBLE
        if self.kind == "grip":
            if s & Status.GRIPPED and s & Status.SUCCESS:
                return Outcome.GRIPPED
            if s & Status.NO_WORKPIECE:
                return Outcome.NO_WORKPIECE
            if s & Status.WRONG_WORKPIECE:
                return Outcome.WRONG_WORKPIECE
            return Outcome.PENDING
        if not s & Status.SUCCESS:
            return Outcome.PENDING
        if self.kind in ("move", "release") and not s & Status.REACHED:
            return Outcome.BLOCKED
        return Outcome.DONE
