"""The Robotiq URCap's ASCII socket (TCP 63352 on a UR controller), sans-IO: lines out, lines in.

``SET VAR VALUE [VAR VALUE ...]`` is answered ``ack``; ``GET VAR`` is answered ``VAR VALUE``. Request
variables ACT, GTO, ATR, ARD, POS (rPR), SPE, FOR; status variables STA, OBJ, FLT, PRE (the position request
echo), and GET POS reads gPO. Values are the register bytes. Facts: docs/protocols-robotiq.md §5.
"""

from __future__ import annotations

from dataclasses import dataclass

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
