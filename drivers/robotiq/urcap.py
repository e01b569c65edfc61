"""The Robotiq URCap's ASCII socket (TCP 63352 on a UR controller), sans-IO: lines out, lines in.

``SET VAR VALUE [VAR VALUE ...]`` is answered ``ack``; ``GET VAR`` is answered ``VAR VALUE``. Request
variables ACT, GTO, ATR, ARD, POS (rPR), SPE, FOR; status variables STA, OBJ, FLT, PRE (the position request
echo), and GET POS reads gPO. Values are the register bytes. Facts: docs/protocols-robotiq.md §5.
"""

from __future__ import annotations

import contextlib
import socket
import threading
import time
from dataclasses import dataclass

from ..errors import ConnectionLost, GripperTimeout, ProtocolError
from .registers import URCAP_PORT, ActivationState, Command, ObjectDetection, Status

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


class UrcapClient:
    """The register view over the URCap's socket: ``read_status()`` (one GET per field) and
    ``write_command()`` (one SET of every request field), so the Robotiq backend drives a gripper through the
    URCap as it does over Modbus. gCU is not offered by the URCap: the status reads it as 0."""

    def __init__(
        self, host: str, port: int = URCAP_PORT, *, device: str, timeout: float = 1.0, slave: int = 9
    ):
        self.device = device
        self.timeout = timeout
        self.slave = slave
        self._lock = threading.Lock()
        self._parser = LineParser()
        self._lost: BaseException | None = None
        try:
            self._sock = socket.create_connection((host, port), timeout=timeout)
        except OSError as exc:
            raise ConnectionLost(
                f"cannot connect to {host}:{port}: {exc}", device=device, command="open"
            ) from exc

    @property
    def alive(self) -> bool:
        return self._lost is None

    def _exchange(self, line: bytes, command: str) -> Reply:
        with self._lock:
            if self._lost is not None:
                raise ConnectionLost(f"the link is down ({self._lost})", device=self.device, command=command)
            deadline = time.monotonic() + self.timeout
            try:
                self._sock.sendall(line)
                while True:
                    left = deadline - time.monotonic()
                    if left <= 0:
                        raise GripperTimeout(
                            f"no answer to {line.decode().strip()!r} within {self.timeout:g} s",
                            device=self.device,
                            command=command,
                        )
                    self._sock.settimeout(left)
                    try:
                        data = self._sock.recv(4096)
                    except TimeoutError:
                        continue
                    if not data:
                        raise ConnectionLost(
                            "the URCap closed the connection", device=self.device, command=command
                        )
                    try:
                        replies = self._parser.feed(data)
                    except ValueError as exc:
                        raise ProtocolError(str(exc), device=self.device, command=command) from None
                    if replies:
                        return replies[0]
            except OSError as exc:
                self._lost = exc
                raise ConnectionLost(f"URCap socket: {exc}", device=self.device, command=command) from exc
            except ConnectionLost as exc:
                self._lost = exc
                raise

    def get(self, name: str, *, command: str = "status") -> int:
        reply = self._exchange(get_line(name), command)
        if reply.name != name or reply.value is None:
            raise ProtocolError(f"asked {name}, got {reply.raw!r}", device=self.device, command=command)
        return reply.value

    def read_status(self, *, command: str = "status") -> Status:
        v = {
            name: self.get(name, command=command)
            for name in ("ACT", "GTO", "STA", "OBJ", "FLT", "PRE", "POS")
        }
        return Status(
            act=bool(v["ACT"]),
            gto=bool(v["GTO"]),
            sta=ActivationState(v["STA"] & 3),
            obj=ObjectDetection(v["OBJ"] & 3),
            fault=v["FLT"] & 0x0F,
            controller_fault=0,
            position_echo=v["PRE"],
            position=v["POS"],
            current=0,
        )

    def write_command(self, cmd: Command, *, command: str = "command") -> None:
        line = set_line(
            ACT=int(cmd.act), GTO=int(cmd.gto), ATR=int(cmd.atr), ARD=int(cmd.ard),
            SPE=cmd.speed, FOR=cmd.force, POS=cmd.position,
        )  # fmt: skip
        reply = self._exchange(line, command)
        if reply.name is not None:
            raise ProtocolError(f"SET answered {reply.raw!r}, not ack", device=self.device, command=command)

    def close(self) -> None:
        with contextlib.suppress(OSError):
            self._sock.close()
        if self._lost is None:
            self._lost = ConnectionLost("closed", device=self.device)
