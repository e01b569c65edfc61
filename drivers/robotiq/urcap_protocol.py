"""The Robotiq URCap's ASCII socket (TCP 63352 on a UR controller), sans-IO: lines out, replies in.

The codec both sides share: the client (:mod:`.urcap`, over a TCP link of the backend kit) and the simulator
(:mod:`.sim.server`). Nothing here does I/O.

Requests are lines: ``SET VAR VALUE [VAR VALUE ...]\\n`` and ``GET VAR\\n``. The replies are not framed alike
(docs/protocols-robotiq.md §5 names the public sources): a SET is answered by the three bytes ``ack`` with no
line end (ur_rtde compares a raw read to ``"ack"``, the URCap's own script reads three bytes), a GET by
``VAR VALUE\\n``. A reply therefore ends at its known form, not only at a newline: :class:`ReplyParser` takes
``ack`` with or without a line end, and ``VAR VALUE`` at its line end or once it has the three digits a byte
can have. Request variables ACT, GTO, ATR, ARD, POS (rPR), SPE, FOR; status variables STA, OBJ, FLT, PRE (the
position request echo), and GET POS reads gPO. Values are the register fields, each in its own range.
"""

from __future__ import annotations

import re
from collections.abc import Mapping
from dataclasses import dataclass

from .registers import ActivationState, Command, ObjectDetection, Status

SETTABLE = ("ACT", "GTO", "ATR", "ARD", "POS", "SPE", "FOR", "SID")
READABLE = ("ACT", "GTO", "STA", "OBJ", "FLT", "POS", "PRE", "SPE", "FOR")
# The largest value each readable variable can have: its field's width in the register map (§1 of the docs):
# a bit, the 2-bit gSTA and gOBJ, and bytes (gFLT's byte carries the controller's kFLT nibble beside gFLT).
MAXIMA = {"ACT": 1, "GTO": 1, "STA": 3, "OBJ": 3, "FLT": 255, "POS": 255, "PRE": 255, "SPE": 255, "FOR": 255}
ACK = "ack"
ACK_REPLY = b"ack"  # what the URCap answers a SET: three bytes, no line end
VALUE_DIGITS = 3  # a byte has at most three decimal digits: ``VAR ddd`` is complete without its line end
MAX_GARBAGE_REPORT = 40  # bytes of dropped garbage quoted in a message


def set_line(**values: int) -> bytes:
    """``SET POS 100 GTO 1\\n`` from ``set_line(POS=100, GTO=1)`` (order kept: the URCap applies them in
    turn)."""
    if not values:
        raise ValueError("SET needs at least one variable")
    parts = []
    for name, value in values.items():
        if name not in SETTABLE:
            raise ValueError(f"{name!r} is not a settable URCap variable ({', '.join(SETTABLE)})")
        if isinstance(value, bool) or not isinstance(value, int) or not 0 <= value <= 255:
            raise ValueError(f"{name} takes a byte 0..255, not {value!r}")
        parts.append(f"{name} {value}")
    return f"SET {' '.join(parts)}\n".encode("ascii")


def get_line(name: str) -> bytes:
    if name not in READABLE:
        raise ValueError(f"{name!r} is not a readable URCap variable ({', '.join(READABLE)})")
    return f"GET {name}\n".encode("ascii")


def get_reply(name: str, value: int) -> bytes:
    """The device side of GET: ``VAR VALUE\\n``."""
    return f"{name} {value}\n".encode("ascii")


@dataclass(frozen=True, slots=True)
class Reply:
    """One reply: ``ack`` (``name`` None) or ``VAR VALUE``; ``error`` says why a ``VAR VALUE`` is no value
    (out of its variable's range: ``value`` is then None)."""

    name: str | None
    value: int | None
    raw: str
    error: str | None = None


_VARIABLE = "|".join(READABLE).encode()
# Where a reply may start: ``ack``, or a readable variable and a space (what resynchronisation looks for).
_START = re.compile(rb"ack|(?:" + _VARIABLE + rb") ")
_VALUE = re.compile(rb"(" + _VARIABLE + rb") ([0-9]+)")
_SPACE = b" \t\r\n\0"
_LONGEST_START = 4  # "POS ": the most a cut-short reply can hold before its first digit


class ReplyParser:
    """Bytes in, replies out, each ended by its known form (``ack``; ``VAR VALUE`` at its line end or at three
    digits). Bytes that start no reply are dropped up to where one may start (resynchronisation: counted in
    :attr:`dropped`, the first of them kept in :attr:`garbage` for a message)."""

    def __init__(self) -> None:
        self._buf = bytearray()
        self.dropped = 0
        self.garbage = b""

    def feed(self, data: bytes) -> list[Reply]:
        self._buf += data
        out: list[Reply] = []
        buf = self._buf
        while True:
            del buf[: len(buf) - len(buf.lstrip(_SPACE))]
            if not buf:
                return out
            if buf.startswith(ACK_REPLY):
                del buf[: len(ACK_REPLY)]
                out.append(Reply(None, None, ACK))
                continue
            match = _VALUE.match(buf)
            if match is not None:
                if match.end() == len(buf) and len(match.group(2)) < VALUE_DIGITS:
                    return out  # more digits may follow
                reply = _reply(match.group(1).decode(), match.group(2).decode())
                del buf[: match.end()]
                out.append(reply)
                continue
            if _could_start(bytes(buf)):
                return out  # the start of a reply, cut short
            found = _START.search(buf, 1)
            cut = found.start() if found is not None else len(buf)
            if found is None:  # keep a tail that may begin the next reply
                tail = next((k for k in range(_LONGEST_START, 0, -1) if _could_start(bytes(buf[-k:]))), 0)
                cut = max(1, len(buf) - tail)
            self.garbage = bytes(buf[: min(cut, MAX_GARBAGE_REPORT)])
            self.dropped += cut
            del buf[:cut]


def _could_start(data: bytes) -> bool:
    """Whether ``data`` is the beginning of a reply cut short (``ac``, ``PO``, ``POS ``)."""
    if ACK_REPLY.startswith(data):
        return True
    name, space, rest = data.partition(b" ")
    if not space:
        return any(v.encode().startswith(name) for v in READABLE)
    return not rest and name in {v.encode() for v in READABLE}


def _reply(name: str, digits: str) -> Reply:
    raw = f"{name} {digits if len(digits) <= MAX_GARBAGE_REPORT else digits[:MAX_GARBAGE_REPORT] + '...'}"
    significant = digits.lstrip("0")
    if len(significant) > VALUE_DIGITS or int(significant or "0") > MAXIMA[name]:  # int() of 3 digits at most
        return Reply(name, None, raw, f"{raw} is out of range (0..{MAXIMA[name]})")
    return Reply(name, int(significant or "0"), raw)


def parse_command(line: str) -> tuple[str, dict[str, int]] | tuple[str, str]:
    """The device side (the simulator): ``("SET", {VAR: value, ...})`` or ``("GET", VAR)``; ValueError
    for anything else."""
    words = line.split()
    if len(words) >= 3 and words[0] == "SET" and len(words) % 2 == 1:
        values: dict[str, int] = {}
        for name, value in zip(words[1::2], words[2::2], strict=True):
            if name not in SETTABLE or not value.isdigit() or int(value) > 255:
                raise ValueError(f"bad SET {name} {value}")
            values[name] = int(value)
        return "SET", values
    if len(words) == 2 and words[0] == "GET" and words[1] in READABLE:
        return "GET", words[1]
    raise ValueError(f"not a URCap command: {line[:60]!r}")


# -- the register view: what the URCap's variables are in the Modbus register map ---------------------------

STATUS_VARIABLES = ("ACT", "GTO", "STA", "OBJ", "FLT", "PRE", "POS")  # GET, one line each, for a Status


def command_line(cmd: Command) -> bytes:
    """The one SET line that writes every request field of ``cmd``."""
    return set_line(
        ACT=int(cmd.act), GTO=int(cmd.gto), ATR=int(cmd.atr), ARD=int(cmd.ard),
        SPE=cmd.speed, FOR=cmd.force, POS=cmd.position,
    )  # fmt: skip


def status_of(values: Mapping[str, int]) -> Status:
    """A :class:`Status` from the values of :data:`STATUS_VARIABLES`; gCU is not offered by the URCap (None:
    unreported, not 0). FLT is the status byte's fault field: gFLT, kFLT in its high nibble."""
    return Status(
        act=bool(values["ACT"]),
        gto=bool(values["GTO"]),
        sta=ActivationState(values["STA"] & 3),
        obj=ObjectDetection(values["OBJ"] & 3),
        fault=values["FLT"] & 0x0F,
        controller_fault=values["FLT"] >> 4,
        position_echo=values["PRE"],
        position=values["POS"],
        current=None,
    )


def command_after_set(current: Command, values: Mapping[str, int]) -> Command:
    """The device side of SET: the request block ``current`` with the variables of one SET line applied
    (a variable left out keeps its value; SID, the slave id, is not a request field)."""
    return Command(
        act=bool(values.get("ACT", current.act)),
        gto=bool(values.get("GTO", current.gto)),
        atr=bool(values.get("ATR", current.atr)),
        ard=bool(values.get("ARD", current.ard)),
        position=values.get("POS", current.position),
        speed=values.get("SPE", current.speed),
        force=values.get("FOR", current.force),
    )


def variable_of(name: str, status: Status, command: Command) -> int:
    """The device side of GET: the value of readable variable ``name`` (SPE and FOR read the request)."""
    values = {
        "ACT": int(status.act), "GTO": int(status.gto), "STA": int(status.sta), "OBJ": int(status.obj),
        "FLT": status.fault, "PRE": status.position_echo, "POS": status.position, "SPE": command.speed,
        "FOR": command.force,
    }  # fmt: skip
    return values[name]
