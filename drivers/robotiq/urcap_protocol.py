"""The Robotiq URCap's ASCII socket (TCP 63352 on a UR controller), sans-IO: lines out, lines in.

The codec both sides share: the client (:mod:`.urcap`, over a TCP link of the backend kit) and the simulator
(:mod:`.sim.server`). Nothing here does I/O.

``SET VAR VALUE [VAR VALUE ...]`` is answered ``ack``; ``GET VAR`` is answered ``VAR VALUE``. Request
variables ACT, GTO, ATR, ARD, POS (rPR), SPE, FOR; status variables STA, OBJ, FLT, PRE (the position request
echo), and GET POS reads gPO. Values are the register bytes. Facts: docs/protocols-robotiq.md §5.
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass

from .registers import ActivationState, Command, ObjectDetection, Status

SETTABLE = ("ACT", "GTO", "ATR", "ARD", "POS", "SPE", "FOR", "SID")
READABLE = ("ACT", "GTO", "STA", "OBJ", "FLT", "POS", "PRE", "SPE", "FOR")
ACK = "ack"
MAX_LINE = 256  # a reply longer than this is not the URCap's


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


@dataclass(frozen=True, slots=True)
class Reply:
    """One reply line: ``ack`` (``name`` None) or ``VAR VALUE``."""

    name: str | None
    value: int | None
    raw: str


class LineParser:
    """Bytes in, reply lines out; a line that is neither ``ack`` nor ``VAR INT`` raises ValueError naming
    it."""

    def __init__(self) -> None:
        self._buf = bytearray()

    def feed(self, data: bytes) -> list[Reply]:
        self._buf += data
        out = []
        while b"\n" in self._buf:
            raw, _, rest = bytes(self._buf).partition(b"\n")
            self._buf = bytearray(rest)
            line = raw.decode("ascii", "replace").strip()
            if line:
                out.append(parse_reply(line))
        if len(self._buf) > MAX_LINE:
            text = bytes(self._buf[:40])
            self._buf.clear()
            raise ValueError(f"no end of line after {MAX_LINE} bytes ({text!r}...)")
        return out


def parse_reply(line: str) -> Reply:
    if line == ACK:
        return Reply(None, None, line)
    name, _, value = line.partition(" ")
    if name in READABLE and value.strip().isdigit():
        return Reply(name, int(value), line)
    raise ValueError(f"not a URCap reply: {line[:60]!r}")


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
    """A :class:`Status` from the values of :data:`STATUS_VARIABLES`; gCU is not offered by the URCap (0)."""
    return Status(
        act=bool(values["ACT"]),
        gto=bool(values["GTO"]),
        sta=ActivationState(values["STA"] & 3),
        obj=ObjectDetection(values["OBJ"] & 3),
        fault=values["FLT"] & 0x0F,
        controller_fault=0,
        position_echo=values["PRE"],
        position=values["POS"],
        current=0,
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
