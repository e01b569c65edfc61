"""The STEPFOC / Spectral Micro UART text protocol as used by the MSG gripper, sans-IO.

Both directions live here so the client and the simulator cannot drift apart: :data:`COMMANDS` (one row per
command: name, answer text, argument range) formats the requests the client sends, parses the answers it
reads and renders the answers the simulator prints. The multi-line answers (``#Gripinfo``, ``#Info``) have
their own line tables, :data:`GRIPINFO_FIELDS` and :data:`INFO_HEADER` / :data:`INFO_STATUS`, used the same
three ways.

Wire facts (docs/protocols.md §2 "UART text interface", which wins over the MSG document ``004_…``): a
command is ``#Name`` (get) or ``#Name N`` (set) ended by ``\\n``; ``#`` resets the device's receiver; name
and argument together are at most 20 characters; no echo; every known gripper command answers with one line
(``Gripinfo`` with eleven) ending in ``\\r\\n``; unknown names get nothing or ``Unknown command``. The
``#Info`` status lines and the ``Clear`` command are not in the notes; they are read from the public STEPFOC
firmware (``communication.cpp``), and a line we do not know is kept raw rather than guessed at.
"""

from __future__ import annotations

import re
from collections.abc import Callable, Iterable
from dataclasses import dataclass, field
from typing import Any

from ..errors import LimitError, ProtocolError
from .can_protocol import Detection

BAUDRATE = 256_000  # docs/protocols.md §2 UART
MAX_COMMAND_CHARS = 20  # name + argument, docs/protocols.md §2 UART
MAX_NAME_CHARS = 19  # the firmware reads the name with sscanf("%19s")
UNKNOWN_COMMAND = "Unknown command"  # docs/protocols.md §2 UART
LINE_END = "\r\n"  # the firmware prints with Arduino println
# the driver can push 2800 mA and the firmware never clamps (docs/protocols.md §2, physical facts)
MAX_CURRENT_MA = 2800

_NAME_RE = re.compile(r"[A-Za-z][A-Za-z0-9_]*")
_INT_RE = re.compile(r"[+-]?\d+")
_FLOAT_RE = re.compile(r"[+-]?(\d+(\.\d*)?|\.\d+)")


# ----------------------------------------------------------------------------------------------------
# Values on the wire


def parse_int(text: str) -> int:
    """A decimal integer as Arduino ``print`` writes it; anything else is a ValueError, never a guess."""
    text = text.strip()
    if not _INT_RE.fullmatch(text):
        raise ValueError(f"not an integer: {text!r}")
    return int(text)


def parse_float(text: str) -> float:
    """A decimal number as Arduino ``print(float, digits)`` writes it (integers accepted too)."""
    text = text.strip()
    if not _FLOAT_RE.fullmatch(text):
        raise ValueError(f"not a number: {text!r}")
    return float(text)


def format_float(value: float, digits: int = 5) -> str:
    """Arduino ``println(x, 5)``: fixed point with ``digits`` decimals."""
    return f"{value:.{digits}f}"


def check_range(value: float, valid: tuple[float, float], what: str, line: str) -> None:
    """ProtocolError naming the line when ``value`` is outside its protocol range ``valid`` (inclusive)."""
    lo, hi = valid
    if not lo <= value <= hi:  # NaN fails this too
        raise ProtocolError(f"{what} {value} outside {lo}..{hi} in the line {line.rstrip()[:80]!r}")


def atoi(text: str) -> int:
    """C ``atoi`` as the firmware applies it to an argument: leading number or 0, never an error.

    The simulator must accept what the firmware accepts (``#Grippos 12abc`` sets 12, ``#Grippos x`` sets 0).
    """
    m = re.match(r"\s*([+-]?\d+)", text)
    if not m:
        return 0
    value = int(m.group(1))
    # a C int wraps; keep it in 32 bits like the device would
    return (value + 2**31) % 2**32 - 2**31


def _value_after(line: str, prefix: str, suffix: str = "") -> str | None:
    """The text between ``prefix`` and ``suffix`` of ``line`` (trailing blanks ignored), or None."""
    line = line.rstrip()
    if not line.startswith(prefix):
        return None
    rest = line[len(prefix) :]
    if suffix:
        suffix = suffix.rstrip()
        if not rest.endswith(suffix):
            return None
        rest = rest[: len(rest) - len(suffix)]
    return rest


# ----------------------------------------------------------------------------------------------------
# The command table


@dataclass(frozen=True, slots=True)
class Answer:
    """One single-line answer: the command it belongs to and its value (None for ``Gripcal``)."""

    command: str
    value: int | None


@dataclass(frozen=True, slots=True)
class CommandSpec:
    """One row of the UART command table.

    ``answer`` is the fixed text of the answer line: the prefix before the number when ``has_value``, the
    whole line otherwise (trailing blanks are part of what the firmware prints, not of what we require). For
    the multi-line answers it is the text of the first line. ``lines`` is the number of answer lines, 0 when
    it varies (``Info``). ``arg_range`` is what a set may carry (None: the command takes no argument).
    """

    name: str
    answer: str
    settable: bool
    arg_range: tuple[int, int] | None = None
    has_value: bool = True
    lines: int = 1
    doc: str = ""

    def parse(self, line: str) -> Answer | None:
        """This command's answer in ``line``, or None when the line is something else (garbage, other).

        A line that is this answer but carries a number outside the command's range (a position of 300, a
        bit of 7) is a ProtocolError naming the line: it is not noise to skip, and not a value to use."""
        if self.lines != 1:
            return None
        if not self.has_value:
            return Answer(self.name, None) if line.rstrip() == self.answer.rstrip() else None
        text = _value_after(line, self.answer)
        if text is None:
            return None
        try:
            number = parse_int(text)
        except ValueError:
            return None
        if self.arg_range is not None:
            check_range(number, self.arg_range, self.name, line)
        return Answer(self.name, number)

    def render(self, value: int | None = None) -> str:
        """The answer line the firmware prints (without the line end)."""
        if self.lines != 1:
            raise ValueError(f"{self.name} answers with several lines; use render_gripinfo/render_info")
        if not self.has_value:
            return self.answer
        if value is None:
            raise ValueError(f"{self.name} answers with a value")
        return f"{self.answer}{int(value)}"


def _spec(*args: Any, **kw: Any) -> tuple[str, CommandSpec]:
    spec = CommandSpec(*args, **kw)
    return spec.name, spec


# docs/protocols.md §2 UART (answers) and the MSG document 004_… (ranges); "Clear" from the public firmware.
COMMANDS: dict[str, CommandSpec] = dict(
    [
        _spec("Gripper", "Gripper: ", True, (0, 1), doc="set/get 'am I a gripper'"),
        _spec("Gripcal", "Gripper calibration! ", False, has_value=False, doc="start calibration"),
        _spec(
            "Grippos",
            "Gripper current position is: ",
            True,
            (0, 255),
            doc="set: position setpoint, activates and starts the motion; answers the ACTUAL position",
        ),
        _spec("Gripvel", "Gripper velocity setpoint is: ", True, (0, 255), doc="velocity setpoint"),
        _spec(
            "Gripcur", "Gripper current setpoint is: ", True, (0, MAX_CURRENT_MA), doc="current setpoint, mA"
        ),
        _spec("Gripact", "Gripper activation bit is: ", True, (0, 1), doc="activation bit"),
        _spec("Gripstop", "Gripper estop bit is: ", True, (0, 1), doc="estop bit"),
        _spec("Gripinfo", "I am a gripper", False, has_value=False, lines=11, doc="gripper status, 11 lines"),
        _spec("Info", "Hardware version: ", False, has_value=False, lines=0, doc="driver information"),
        _spec("Clear", "Clear errors", False, has_value=False, doc="clear all errors, mode idle"),
        _spec("Idle", "Idle", False, has_value=False, doc="driver mode idle (communication.cpp)"),
    ]
)


# The names the firmware's parser passes on (public STEPFOC firmware, SerialPacketParser.cpp ``parse``): one
# list for "#NAME ARG", one for "#NAME". A line whose name is not in its list is dropped without an answer;
# a listed name that communication.cpp does not dispatch is answered "Unknown command" (docs/protocols.md §2,
# "Firmware behaviour a client must survive").
# Both lists hold these; only the differences stand apart below.
_PARSER_NAMES_BOTH = frozenset(
    [
        "Iq",
        "Id",
        "Uq",
        "Ud",
        "V",
        "Vlim",
        "P",
        "PD",
        "Kpp",
        "Kpv",
        "Kpiq",
        "Kpid",
        "Kiv",
        "Kiiq",
        "Kiid",
        "KP",
        "KD",
        "PDV",
        "PDI",
        "R",
        "L",
        "Kt",
        "KV",
        "flux",
        "Cal",
        "Save",
        "Reset",
        "Ilim",
        "Dir",
        "Temp",
        "Magnet",
        "Term",
        "Mode",
        "Vbus",
        "Vmin",
        "Vmax",
        "Error",
        "Clear",
        "Default",
        "SIN",
        "SPWM",
        "Iabc",
        "Close",
        "Cbw",
        "Resv",
        "Calpwr",
        "Openv",
        "Opens",
        "Vp",
        "Calibrated",
        "Param",
        "PP",
        "Openloop",
        "LED",
        "Cyc",
        "Cyca",
        "CANID",
        "SERNUM",
        "Info",
        "Vlimit",
        "Phase",
        "Activate",
        "Gripper",
        "Gripcal",
        "Grippos",
        "Gripvel",
        "Gripcur",
        "Gripact",
        "Gripstop",
        "Gripinfo",
        "Rstint",
        "Pullconfig",
        "Tlim",
        "Brake",
        "HALL",
        "Coast",
        "Calangle",
        "Offset",
        "Iqoffset",
        "microstep",
        "stepinterval",
        "gosteps",
    ]
)
PARSER_NAMES_WITH_ARG = _PARSER_NAMES_BOTH | {"zz"}
PARSER_NAMES_BARE = _PARSER_NAMES_BOTH | {"EN", "PWM", "Idle"}


def parser_knows(req: Request) -> bool:
    """Whether the firmware's parser passes ``req`` on to the command dispatch (else: no answer at all)."""
    names = PARSER_NAMES_BARE if req.argument is None else PARSER_NAMES_WITH_ARG
    return req.name in names


# ``#Mode`` prints the driver mode as text (communication.cpp); mode 11 (gripper) has no line and gets NO
# answer, so a client reads silence as "neither idle nor calibrating".
MODE_LINES: dict[int, str] = {
    0: "Idle mode ",
    1: "Position control ",
    2: "Speed control ",
    3: "Current control ",
    4: "PD control ",
    5: "Open loop",
    6: "Gripper mode",
    7: "Gripper calib mode",
}
MODE_IDLE, MODE_CALIBRATE = 0, 7


def parse_mode(line: str) -> int | None:
    """The driver mode a ``#Mode`` answer line names, or None for any other line."""
    text = line.rstrip()
    for mode, label in MODE_LINES.items():
        if text == label.rstrip():
            return mode
    return None


def spec(name: str) -> CommandSpec:
    try:
        return COMMANDS[name]
    except KeyError:
        raise ProtocolError(f"unknown UART command {name!r}", command=name) from None


def format_command(name: str, value: int | None = None) -> bytes:
    """``#Name\\n`` or ``#Name N\\n``, refused before anything is sent when the device would not take it.

    Any syntactically valid name is allowed (so tools can probe names the table does not know); the table's
    commands are also checked for whether they take an argument and for its range.
    """
    if not isinstance(name, str) or not _NAME_RE.fullmatch(name):
        raise ValueError(f"invalid UART command name {name!r} (letters, digits, '_'; starts with a letter)")
    if len(name) > MAX_NAME_CHARS:
        raise LimitError(f"command name longer than {MAX_NAME_CHARS} characters", command=name)
    known = COMMANDS.get(name)
    if value is None:
        text = name
    else:
        if isinstance(value, bool):
            value = int(value)
        if not isinstance(value, int):
            raise ValueError(f"{name}: argument must be an integer, not {value!r}")
        if known is not None:
            if not known.settable or known.arg_range is None:
                raise ValueError(f"{name} takes no argument")
            lo, hi = known.arg_range
            if not lo <= value <= hi:
                raise LimitError(f"argument {value} outside {lo}..{hi}", command=name)
        text = f"{name} {value}"
    # docs/protocols.md §2: command and argument together at most 20 characters (the firmware drops
    # longer lines)
    if len(text) - (value is not None) > MAX_COMMAND_CHARS:
        raise LimitError(
            f"command and argument longer than {MAX_COMMAND_CHARS} characters: {text!r}", command=name
        )
    return f"#{text}\n".encode("ascii")


def is_unknown_command(line: str) -> bool:
    return line.strip() == UNKNOWN_COMMAND


def parse_answer(line: str) -> Answer | None:
    """The single-line answer in ``line`` whichever command it belongs to (for monitors), else None.

    ``Gripper current setpoint is: N`` is both Gripcur's answer and line 6 of Gripinfo; it parses as Gripcur.
    """
    for s in COMMANDS.values():
        ans = s.parse(line)
        if ans is not None:
            return ans
    return None


# ----------------------------------------------------------------------------------------------------
# Line splitting (client side)


@dataclass(frozen=True, slots=True)
class Line:
    """One received line without its line end; ``text`` is ``raw`` decoded, bad bytes replaced."""

    text: str
    raw: bytes


@dataclass(frozen=True, slots=True)
class LineTooLong:
    """A line longer than the splitter's bound was dropped (``size`` bytes, line end included)."""

    size: int


SplitEvent = Line | LineTooLong


class LineSplitter:
    """Cuts a byte stream into lines at ``\\n`` (a ``\\r`` before it is dropped), for any chunking.

    A device answer is at most a few dozen characters, so a longer line is noise (a wrong baud rate, another
    program on the port): it is dropped and reported instead of growing the buffer without bound. Blank lines
    carry nothing and are skipped. Never raises on any input.
    """

    def __init__(self, max_line: int = 256) -> None:
        if max_line < 1:
            raise ValueError("max_line must be positive")
        self.max_line = max_line
        self._buf = bytearray()
        self._dropping = 0  # bytes of an over-long line dropped so far

    @property
    def buffered(self) -> int:
        return len(self._buf)

    def reset(self) -> bytes:
        """Forget a partial line (before a new command); returns what was dropped."""
        dropped = bytes(self._buf)
        self._buf.clear()
        self._dropping = 0
        return dropped

    def feed(self, data: bytes) -> list[SplitEvent]:
        out: list[SplitEvent] = []
        self._buf += data
        while True:
            end = self._buf.find(b"\n")
            if end < 0:
                if len(self._buf) > self.max_line:
                    self._dropping += len(self._buf)
                    self._buf.clear()
                return out
            raw = bytes(self._buf[:end])
            del self._buf[: end + 1]
            if self._dropping or len(raw) > self.max_line:
                out.append(LineTooLong(self._dropping + len(raw) + 1))
                self._dropping = 0
                continue
            if raw.endswith(b"\r"):
                raw = raw[:-1]
            if not raw.strip():
                continue
            out.append(Line(raw.decode("utf-8", "replace"), raw))


# ----------------------------------------------------------------------------------------------------
# Gripinfo


@dataclass(frozen=True, slots=True)
class GripInfo:
    """The eleven lines of ``#Gripinfo`` as one record (docs/protocols.md §2 UART)."""

    is_gripper: bool
    calibrated: bool
    activated: bool
    position_setpoint: int
    speed_setpoint: int
    current_setpoint: int
    estop: bool
    action: bool
    detection: Detection | int  # an out-of-range value is kept as the int the device printed
    max_open_position: int
    max_closed_position: int


GRIPINFO_FIRST_LINE = {True: "I am a gripper", False: "I am not a gripper "}  # docs/protocols.md §2 UART

# (field, line prefix) of Gripinfo lines 2..11, in the order the firmware prints them
# (docs/protocols.md §2 UART)
GRIPINFO_FIELDS: tuple[tuple[str, str], ...] = (
    ("calibrated", "Gripper calibrated is: "),
    ("activated", "Gripper activated is: "),
    ("position_setpoint", "Gripper position setpoint is: "),
    ("speed_setpoint", "Gripper speed setpoint is: "),
    ("current_setpoint", "Gripper current setpoint is: "),
    ("estop", "Gripper estop status: "),
    ("action", "Gripper action status: "),
    ("detection", "Gripper object detection status: "),
    ("max_open_position", "Gripper max open position: "),
    ("max_closed_position", "Gripper max closed position: "),
)
_BOOL_FIELDS = frozenset({"calibrated", "activated", "estop", "action"})
_I32 = (-(2**31), 2**31 - 1)
# Protocol ranges of the Gripinfo values (docs/protocols.md §2: bytes 0..255, current 0..2800 mA, detection
# 0..3, flags 0/1; the calibrated end stops are encoder ticks, C ints in the firmware)
GRIPINFO_RANGES: dict[str, tuple[int, int]] = {
    "calibrated": (0, 1),
    "activated": (0, 1),
    "position_setpoint": (0, 255),
    "speed_setpoint": (0, 255),
    "current_setpoint": (0, MAX_CURRENT_MA),
    "estop": (0, 1),
    "action": (0, 1),
    "detection": (0, 3),
    "max_open_position": _I32,
    "max_closed_position": _I32,
}


def _gripinfo_first(line: str) -> bool | None:
    for value, text in GRIPINFO_FIRST_LINE.items():
        if line.rstrip() == text.rstrip():
            return value
    return None


def _gripinfo_value(name: str, number: int) -> Any:
    if name in _BOOL_FIELDS:
        return bool(number)
    if name == "detection":
        try:
            return Detection(number)
        except ValueError:
            return number
    return number


def render_gripinfo(info: GripInfo) -> list[str]:
    """The eleven lines the firmware prints for ``info`` (without line ends)."""
    lines = [GRIPINFO_FIRST_LINE[bool(info.is_gripper)]]
    for name, prefix in GRIPINFO_FIELDS:
        lines.append(f"{prefix}{int(getattr(info, name))}")
    return lines


class GripInfoAssembler:
    """Collects the eleven Gripinfo lines out of a line stream that may hold garbage.

    A record is only produced from eleven consecutive matching lines; a stray line in the middle restarts the
    search (a half record is never returned). ``discarded`` counts lines thrown away.
    """

    def __init__(self) -> None:
        self._values: dict[str, Any] = {}
        self._index = -1  # -1: waiting for the first line
        self.discarded = 0

    def feed(self, line: str) -> GripInfo | None:
        first = _gripinfo_first(line)
        if first is not None:
            if self._index >= 0:
                self.discarded += self._index + 1
            self._values = {"is_gripper": first}
            self._index = 0
            return None
        if self._index >= 0:
            name, prefix = GRIPINFO_FIELDS[self._index]
            text = _value_after(line, prefix)
            number: int | None = None
            if text is not None:
                try:
                    number = parse_int(text)
                except ValueError:
                    number = None
            if number is not None:
                check_range(number, GRIPINFO_RANGES[name], f"Gripinfo {name}", line)
                self._values[name] = _gripinfo_value(name, number)
                self._index += 1
                if self._index == len(GRIPINFO_FIELDS):
                    info = GripInfo(**self._values)
                    self._values = {}
                    self._index = -1
                    return info
                return None
            self.discarded += self._index + 1
            self._values = {}
            self._index = -1
        self.discarded += 1
        return None


def parse_gripinfo(lines: Iterable[str]) -> GripInfo:
    """Exactly the eleven Gripinfo lines -> record; anything else is a ProtocolError."""
    asm = GripInfoAssembler()
    result: GripInfo | None = None
    for line in lines:
        if result is not None:
            raise ProtocolError(f"extra line after Gripinfo: {line!r}", command="Gripinfo")
        result = asm.feed(line)
        if asm.discarded:
            raise ProtocolError(f"unexpected Gripinfo line: {line!r}", command="Gripinfo")
    if result is None:
        raise ProtocolError("Gripinfo incomplete", command="Gripinfo")
    return result


# ----------------------------------------------------------------------------------------------------
# Info


@dataclass(frozen=True, slots=True)
class UartInfo:
    """``#Info``: the four identification lines of docs/protocols.md §2 plus the status lines.

    The status lines are not in the notes; the fields below are the ones the public firmware prints
    (``communication.cpp``), None when a line was absent. Lines we do not recognise stay in ``unknown_lines``
    verbatim, in order. ``calibrated`` is the DRIVER's motor (encoder/phase) calibration that line reports,
    not the gripper's end-stop calibration (that one is :attr:`GripInfo.calibrated`).
    """

    hardware_version: int
    batch_date: int
    software_version: int
    can_id: int
    calibrated: bool | None = None
    thermistor_enabled: bool | None = None
    temperature_c: float | None = None
    vbus_mv: int | None = None
    phase_direction: int | None = None
    phase_order: int | None = None
    pole_pairs: int | None = None
    resistance: float | None = None
    inductance: float | None = None
    kt: float | None = None
    kv: float | None = None
    unknown_lines: tuple[str, ...] = field(default=())


# The identification values are the bytes of CAN frame 25 and the 4-bit node id (docs/protocols.md §2)
INFO_RANGES: dict[str, tuple[float, float]] = {
    "hardware_version": (0, 255),
    "batch_date": (0, 255),
    "software_version": (0, 255),
    "can_id": (0, 15),
    "temperature_c": (-273.15, 1000.0),
    "vbus_mv": (0, 1_000_000),
    "pole_pairs": (0, 1000),
}

# (field, line prefix) of the identification lines, in order (docs/protocols.md §2 UART)
INFO_HEADER: tuple[tuple[str, str], ...] = (
    ("hardware_version", "Hardware version: "),
    ("batch_date", "Batch date: "),
    ("software_version", "Software version: "),
    ("can_id", "CAN ID is: "),
)


@dataclass(frozen=True, slots=True)
class StatusLine:
    """One ``#Info`` status line kind: ``prefix`` number ``suffix`` (public firmware, communication.cpp)."""

    field: str
    prefix: str
    suffix: str
    parse: Callable[[str], Any]
    render: Callable[[Any], str]


INFO_STATUS: tuple[StatusLine, ...] = (
    StatusLine("temperature_c", "Temperature is:", " Degrees", parse_float, lambda v: format_float(v, 2)),
    StatusLine("vbus_mv", "Vbus voltage: ", " mV", parse_int, str),
    StatusLine("phase_direction", "Phase direction: ", "", parse_int, str),
    StatusLine("phase_order", "Phase Order: ", "", parse_int, str),
    StatusLine("pole_pairs", "Number of pole pairs: ", "", parse_int, str),
    StatusLine("resistance", "Single phase resistance: ", "", parse_float, format_float),
    StatusLine("inductance", "Single phase Inductance: ", "", parse_float, format_float),
    StatusLine("kt", "Kt: ", "", parse_float, format_float),
    StatusLine("kv", "KV: ", "", parse_float, format_float),
)
INFO_CALIBRATED = {True: "Calibrated", False: "Not calibrated"}  # public firmware, communication.cpp
INFO_THERMISTOR_OFF = "Termistor is disabled"  # sic, public firmware


def render_info(info: UartInfo) -> list[str]:
    """The lines the firmware prints for ``info``, in its order (absent fields are left out)."""
    lines = [f"{prefix}{int(getattr(info, name))}" for name, prefix in INFO_HEADER]
    if info.calibrated is not None:
        lines.append(INFO_CALIBRATED[bool(info.calibrated)])
    if info.thermistor_enabled is False:
        lines.append(INFO_THERMISTOR_OFF)
    for st in INFO_STATUS:
        value = getattr(info, st.field)
        if value is not None:
            lines.append(f"{st.prefix}{st.render(value)}{st.suffix}")
    lines.extend(info.unknown_lines)
    return lines


class InfoAssembler:
    """Collects ``#Info`` lines out of a line stream that may hold garbage.

    The answer has no fixed length, so the caller decides where it ends (the client sends a second, known
    command behind ``#Info`` and calls :meth:`finish` when its answer arrives). Until the four identification
    lines have arrived in order, other lines are discarded; after them every line is a status line.
    """

    def __init__(self) -> None:
        self._values: dict[str, Any] = {}
        self._index = 0
        self._unknown: list[str] = []
        self.discarded = 0

    @property
    def header_complete(self) -> bool:
        return self._index == len(INFO_HEADER)

    def feed(self, line: str) -> None:
        if _value_after(line, INFO_HEADER[0][1]) is not None:
            self.discarded += self._index + len(self._unknown)
            self._values, self._index, self._unknown = {}, 0, []
        if self._index < len(INFO_HEADER):
            name, prefix = INFO_HEADER[self._index]
            text = _value_after(line, prefix)
            try:
                number = parse_int(text) if text is not None else None
            except ValueError:
                number = None
            if number is None:
                self.discarded += self._index + 1
                self._values, self._index = {}, 0
                return
            check_range(number, INFO_RANGES[name], f"Info {name}", line)
            self._values[name] = number
            self._index += 1
            return
        self._status_line(line)

    def _status_line(self, line: str) -> None:
        text = line.rstrip()
        for value, label in INFO_CALIBRATED.items():
            if text == label:
                self._values["calibrated"] = value
                return
        if text == INFO_THERMISTOR_OFF:
            self._values["thermistor_enabled"] = False
            return
        for st in INFO_STATUS:
            raw = _value_after(line, st.prefix, st.suffix)
            if raw is None:
                continue
            try:
                value = st.parse(raw)
            except ValueError:
                break
            valid = INFO_RANGES.get(st.field, (-1e30, 1e30))  # floats: finite and of a sane size
            check_range(value, valid, f"Info {st.field}", line)
            self._values[st.field] = value
            if st.field == "temperature_c":
                self._values["thermistor_enabled"] = True
            return
        self._unknown.append(line)

    def finish(self) -> UartInfo:
        if not self.header_complete:
            raise ProtocolError("Info answer incomplete (identification lines missing)", command="Info")
        info = UartInfo(**self._values, unknown_lines=tuple(self._unknown))
        self._values, self._index, self._unknown = {}, 0, []
        return info


def parse_info(lines: Iterable[str]) -> UartInfo:
    asm = InfoAssembler()
    for line in lines:
        asm.feed(line)
        if asm.discarded:
            raise ProtocolError(f"unexpected Info line: {line!r}", command="Info")
    return asm.finish()


# ----------------------------------------------------------------------------------------------------
# Device side (the simulator's receiver)


@dataclass(frozen=True, slots=True)
class Request:
    """A command line as the firmware's parser accepted it; ``argument`` is None for a get."""

    name: str
    argument: str | None


@dataclass(frozen=True, slots=True)
class Rejected:
    """A complete line the firmware's parser throws away silently (no ``#``, too long, malformed)."""

    raw: bytes
    reason: str


class CommandReceiver:
    """The device's byte-at-a-time command parser (public firmware ``SerialPacketParser``).

    ``#`` restarts the line; bytes beyond the buffer are dropped (including a ``\\n``, so an over-long line is
    only ended by the next ``#``); a line is ``#NAME`` or ``#NAME ARG`` with name and argument together at
    most 20 characters. ``buffer_size`` is the firmware's buffer (its size is not published; 64 assumed).
    """

    def __init__(self, buffer_size: int = 64) -> None:
        self.buffer_size = buffer_size
        self._buf = bytearray()

    def reset(self) -> None:
        self._buf.clear()

    def feed(self, data: bytes) -> list[Request | Rejected]:
        out: list[Request | Rejected] = []
        for byte in data:
            if byte == 0x23:  # '#'
                self._buf.clear()
            if len(self._buf) < self.buffer_size - 1:
                self._buf.append(byte)
                if byte == 0x0A:
                    out.append(self._complete(bytes(self._buf)))
                    self._buf.clear()
        return out

    @staticmethod
    def _complete(raw: bytes) -> Request | Rejected:
        text = raw.decode("latin-1")
        if not text.startswith("#"):
            return Rejected(raw, "no '#' at the start")
        tokens = text[1:].split()
        if not tokens:
            return Rejected(raw, "empty command")
        name = tokens[0]
        arg = tokens[1] if len(tokens) > 1 else None
        if len(name) > MAX_NAME_CHARS or (arg is not None and len(arg) > MAX_NAME_CHARS):
            return Rejected(raw, "token longer than 19 characters")
        if len(name) + len(arg or "") > MAX_COMMAND_CHARS:
            return Rejected(raw, "command and argument longer than 20 characters")
        return Request(name, arg)


def encode_lines(lines: Iterable[str]) -> bytes:
    """Answer lines as the firmware sends them (``println``: ``\\r\\n`` after each)."""
    return "".join(f"{line}{LINE_END}" for line in lines).encode("latin-1", "replace")


__all__ = [
    "Answer",
    "BAUDRATE",
    "COMMANDS",
    "CommandReceiver",
    "CommandSpec",
    "GRIPINFO_FIELDS",
    "GRIPINFO_FIRST_LINE",
    "GripInfo",
    "GripInfoAssembler",
    "INFO_HEADER",
    "INFO_STATUS",
    "InfoAssembler",
    "Line",
    "LineSplitter",
    "LineTooLong",
    "MAX_COMMAND_CHARS",
    "MODE_LINES",
    "PARSER_NAMES_BARE",
    "PARSER_NAMES_WITH_ARG",
    "Rejected",
    "Request",
    "SplitEvent",
    "UNKNOWN_COMMAND",
    "UartInfo",
    "atoi",
    "encode_lines",
    "format_command",
    "is_unknown_command",
    "parse_answer",
    "parse_gripinfo",
    "parse_info",
    "parse_mode",
    "parser_knows",
    "render_gripinfo",
    "render_info",
    "spec",
]
