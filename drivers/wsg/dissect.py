"""WSG packets as records of :mod:`grippers.drivers.dissect` (the form ``grippers monitor`` prints and the
``grippers.wire`` logger writes): bytes reassembled per direction with the driver's own packet parser, decoded
with its command table."""

from __future__ import annotations

import logging
import time
from collections.abc import Iterator
from typing import Any

from ..dissect import (
    FROM_GRIPPER,
    TO_GRIPPER,
    field_value,
    log_record,
    record,
    register_text_form,
    wire_log,
)
from . import commands, protocol

PROTOCOL = "wsg"

# The WSG's description carries its own arrow (the command table's), which the arrow column says already; its
# id is the command code, named in the description.
register_text_form(PROTOCOL, lambda rec: rec["text"].removeprefix("-> ").removeprefix("<- "))


class WsgStream:
    """Reassembles WSG packets from a byte stream per direction and decodes each with the command table."""

    def __init__(self) -> None:
        self._c = commands
        self._p = protocol
        self._parsers: dict[str, Any] = {}

    def feed(self, direction: str, data: bytes, stamp: float | None) -> Iterator[dict[str, Any]]:
        parser = self._parsers.get(direction)
        if parser is None:
            parser = self._parsers[direction] = self._p.PacketParser()
        for item in parser.feed(data):
            yield self.record(direction, item, stamp)

    def busy(self, direction: str) -> bool:
        parser = self._parsers.get(direction)
        return parser is not None and parser.buffered > 0

    def flush(self, stamp: float | None = None) -> Iterator[dict[str, Any]]:
        """At the end of a capture: report a packet cut short as one record, then what was held behind it."""
        for direction, parser in self._parsers.items():
            cut = bytearray()
            for _ in range(64):  # each round drops at least the three preamble bytes; bounded anyway
                if not parser.buffered:
                    break
                parser.reset()
                for item in parser.feed(b""):
                    if isinstance(item, self._p.Discarded):
                        cut += item.raw
                        continue
                    if cut:
                        yield self._noise(direction, bytes(cut), "incomplete packet at the end", stamp)
                        cut.clear()
                    yield self.record(direction, item, stamp)
            if cut:
                yield self._noise(direction, bytes(cut), "incomplete packet at the end", stamp)

    def _noise(self, direction: str, raw: bytes, reason: str, stamp: float | None) -> dict[str, Any]:
        return record(
            time=stamp,
            protocol=PROTOCOL,
            direction=direction,
            status="noise",
            fields={"bytes": len(raw), "reason": reason},
            text=f"{len(raw)} byte(s) skipped: {reason}",
            raw=raw.hex(),
        )

    def record(self, direction: str, item: Any, stamp: float | None) -> dict[str, Any]:
        p, c = self._p, self._c
        if isinstance(item, p.Discarded):
            return self._noise(direction, item.raw, item.reason, stamp)
        if isinstance(item, p.ChecksumError | p.BadLength):
            problem = (
                f"bad checksum (received {item.received:04X}h, expected {item.expected:04X}h)"
                if isinstance(item, p.ChecksumError)
                else f"bad length ({item.size} bytes, at most {item.max_payload})"
            )
            return record(
                time=stamp,
                protocol=PROTOCOL,
                direction=direction,
                id=f"{item.command:02X}h",
                command=c.command_name(item.command),
                status=problem,
                text=f"{c.command_name(item.command)} {problem}",
                raw=item.raw.hex(),
            )
        packet = item
        if direction == "?":
            direction = self._guess_direction(packet)
        fields: dict[str, Any] = {}
        status: str | None = None
        try:
            if direction == FROM_GRIPPER:
                reply = c.decode_reply(packet.command, packet.payload)
                status, fields = reply.status_name, reply.fields
            else:
                fields = c.decode_request(packet.command, packet.payload)
        except Exception as exc:  # the table could not read it: shown, with why, never fatal
            fields = {"error": str(exc)}
        describe_as = "reply" if direction == FROM_GRIPPER else "request"
        return record(
            time=stamp,
            protocol=PROTOCOL,
            direction=direction,
            id=f"{packet.command:02X}h",
            command=c.command_name(packet.command),
            fields=field_value(fields),
            status=status,
            text=c.describe(packet, describe_as),
            raw=packet.encode().hex(),
        )

    def _guess_direction(self, packet: Any) -> str:
        """Without direction marks: the layout that decodes wins (requests and replies differ in length).

        A reply with an error status carries no data (WSG manual 4.0.x §1.2.2), so a longer payload whose
        first two bytes are not E_SUCCESS is not a reply, even though the status alone would decode."""
        c = self._c
        fits = []
        try:
            c.decode_request(packet.command, packet.payload)
            fits.append(TO_GRIPPER)
        except Exception:
            pass
        try:
            reply = c.decode_reply(packet.command, packet.payload)
            if reply.ok or len(packet.payload) == 2:
                fits.append(FROM_GRIPPER)
        except Exception:
            pass
        return fits[0] if len(fits) == 1 else "?"


class WsgCanDissector:
    """WSG packets carried over CAN (docs/protocols.md §1 CAN: 8-byte chunks of a packet on a command id, the
    replies on id + 1), for :class:`grippers.drivers.dissect.CanDecoder`.

    Those ids are also a STEPFOC node's frames (0x000 is node 0's E-stop, which has no data): a frame is WSG
    when it starts a packet or continues one, unless ``only`` says every frame is WSG (``--protocol wsg``).
    """

    protocol = PROTOCOL

    def __init__(self, wsg_id: int = 0x000, only: bool = False) -> None:
        self.wsg_id = wsg_id
        self.catch_all = only
        self._stream = WsgStream()

    def _direction(self, arbitration_id: int) -> str:
        return FROM_GRIPPER if arbitration_id == self.wsg_id + 1 else TO_GRIPPER

    def claims(self, arbitration_id: int, data: bytes, is_remote: bool) -> bool:
        if is_remote:
            return False
        if self.catch_all:
            return True
        if arbitration_id not in (self.wsg_id, self.wsg_id + 1):
            return False
        return data.startswith(b"\xaa") or self._stream.busy(self._direction(arbitration_id))

    def decode(self, arbitration_id: int, data: bytes, is_remote: bool, stamp: float | None) -> list[dict]:
        return list(self._stream.feed(self._direction(arbitration_id), data, stamp))

    def flush(self) -> Iterator[dict[str, Any]]:
        yield from self._stream.flush()


class WireTap:
    """A WSG transport whose traffic also goes to the ``grippers.wire`` logger, decoded, at DEBUG.

    The client wraps its transport in one only when that logger is enabled at open (``wire_tap``), so the
    common path pays nothing. Bytes are reassembled per direction as the monitor does it, so a packet split
    over reads (serial, CAN) is logged once, whole.
    """

    def __init__(self, transport: Any, device: str) -> None:
        self._transport = transport
        self._device = device
        self._stream = WsgStream()

    def send(self, data: bytes) -> None:
        self._transport.send(data)
        self._log(TO_GRIPPER, data)

    def recv(self, timeout: float) -> bytes:
        data = self._transport.recv(timeout)
        if data:
            self._log(FROM_GRIPPER, data)
        return data

    def _log(self, direction: str, data: bytes) -> None:
        try:
            for rec in self._stream.feed(direction, bytes(data), time.time()):
                log_record(self._device, rec)
        except Exception:  # noqa: BLE001 - a log line must never break the connection
            wire_log.debug("%s %s %d byte(s) not decoded", self._device, direction, len(data))

    def __getattr__(self, name: str) -> Any:  # name, close, connection_oriented, ...: the transport's own
        return getattr(self._transport, name)


def wire_tap(transport: Any, device: str) -> Any:
    """``transport`` itself, or a :class:`WireTap` of it when ``grippers.wire`` logs DEBUG."""
    return WireTap(transport, device) if wire_log.isEnabledFor(logging.DEBUG) else transport
