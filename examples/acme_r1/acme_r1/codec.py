"""The ACME R1's frames, sans-IO: bytes in, requests and replies out; no socket here, so the gripper and its
simulator share one codec.

A frame is ``op addr count data... checksum``: ``op`` one ASCII byte (``R`` read, ``W`` write; the reply's op
is lower case, ``E`` an error whose ``addr`` is the code), ``addr`` and ``count`` one byte each, ``data``
``count`` big-endian 16-bit registers (a read request and a write reply carry none), ``checksum`` the sum of
the bytes before it, modulo 256.
"""

from __future__ import annotations

from dataclasses import dataclass
from enum import IntEnum, IntFlag
from typing import Any


class Reg(IntEnum):
    """The holding registers (units: 0.1 mm, mm/s, N)."""

    TARGET = 0
    SPEED = 1
    FORCE = 2
    CONTROL = 3  # write-only: a Control code
    STATUS = 4  # read-only: Status bits
    POSITION = 5  # read-only
    FORCE_LIMIT = 6  # stored: the most a GO presses with, whatever FORCE asks (N)
    MODEL = 7  # read-only: MODEL_R1


MODEL_R1 = 0x5231  # "R1": what the MODEL register of every R1 holds


class Control(IntEnum):
    GO = 1  # move to TARGET at SPEED, pressing with FORCE on a part
    STOP = 2
    HOME = 3  # reference: a slow opening to the end stop
    RESET = 4  # clear a fault


class Status(IntFlag):
    MOVING = 1
    AT_TARGET = 2
    OBJECT = 4
    FAULT = 8
    HOMED = 16


ERR_ADDRESS, ERR_VALUE, ERR_CHECKSUM = 1, 2, 3


@dataclass(frozen=True)
class Frame:
    op: str
    addr: int
    values: tuple[int, ...] = ()
    count: int | None = None  # a read request's count (it carries no values)

    def encode(self) -> bytes:
        n = len(self.values) if self.count is None else self.count
        body = bytes([ord(self.op), self.addr, n]) + b"".join(v.to_bytes(2, "big") for v in self.values)
        return body + bytes([sum(body) & 0xFF])


class FrameError(ValueError):
    """Bytes that are not a frame (a bad checksum, an unknown op)."""


class Decoder:
    """Feed bytes, take whole frames: ``expect_values(op)`` says which ops carry data."""

    def __init__(self) -> None:
        self._buf = bytearray()

    def feed(self, data: bytes) -> list[Frame]:
        self._buf += data
        frames = []
        while len(self._buf) >= 4:
            op, addr, n = chr(self._buf[0]), self._buf[1], self._buf[2]
            if op not in "RWrwE":
                self._buf.clear()
                raise FrameError(f"unknown op byte 0x{ord(op):02X}")
            size = 3 + (2 * n if op in "Wr" else 0)
            if len(self._buf) < size + 1:
                break
            body, check = bytes(self._buf[:size]), self._buf[size]
            del self._buf[: size + 1]
            if sum(body) & 0xFF != check:
                raise FrameError("bad checksum")
            values = tuple(int.from_bytes(body[i : i + 2], "big") for i in range(3, size, 2))
            frames.append(Frame(op, addr, values, None if values else n))
        return frames


class AcmeDissector:
    """``grippers monitor --protocol acme``: each direction of a byte stream (a capture, the TCP proxy) read
    into the monitor's records with this codec (``feed(direction, data, stamp)``, as the monitor calls it)."""

    protocol = "acme"

    def __init__(self) -> None:
        self._decoders: dict[str, Decoder] = {}

    def feed(self, direction: str, data: bytes, stamp: float | None) -> list[dict[str, Any]]:
        from grippers.kit import monitor_record  # the codec itself needs nothing of grippers

        decoder = self._decoders.setdefault(direction, Decoder())
        try:
            frames = decoder.feed(data)
        except FrameError as exc:
            return [
                monitor_record(
                    time=stamp, protocol=self.protocol, direction=direction, text=str(exc), raw=data.hex()
                )
            ]
        out = []
        for f in frames:
            name = Reg(f.addr).name if f.op != "E" and f.addr < len(Reg) else str(f.addr)
            command = {"R": "read", "W": "write", "r": "read", "w": "write", "E": "error"}[f.op]
            fields = {"register": name, "count": f.count, "values": list(f.values)}
            text = f"{command} {name} " + (" ".join(map(str, f.values)) if f.values else f"x{f.count}")
            out.append(
                monitor_record(
                    time=stamp,
                    protocol=self.protocol,
                    direction=direction,
                    command=command,
                    fields=fields,
                    text=text,
                    raw=f.encode().hex(),
                )
            )
        return out

    def flush(self) -> list[dict[str, Any]]:
        return []
