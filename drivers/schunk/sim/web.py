"""The simulator's web API: the unit's HTTP routes over a kit ``SimServer`` on loopback TCP.

A small HTTP/1.1 request parser (sans-IO: bytes in, requests out; keep-alive, ``Content-Length`` bodies)
and the routes of SCHUNK's dummy (schunk_gripper_dummy/main.py):

- ``GET /adi/data.json?inst=0xNNNN&count=1``: ``["HEX"]`` (upper-case hex of the instance's bytes), ``[]``
  for an instance the unit lacks or a count other than 1; a bare ``GET /adi/data.json`` answers ``[]``
  with 200 (how SCHUNK's driver tests a connection); 503 while the unit is unreachable;
- ``POST /adi/update.json`` with the form fields ``inst`` and ``value``: ``{"result": 0}``, or
  ``{"result": 1}`` for an unknown instance or a value that is not hex;
- ``POST /adi/events.json`` ``{"lose_connection_sec": N}``: the dummy's test hook, unreachable for N s.

Instances are matched as the dummy matches them: ``0x`` and four upper-case hex digits.
"""

from __future__ import annotations

import json
import re
from dataclasses import dataclass

from ...urls import web_fields, web_target
from ..protocol import PARAMETERS, Kind, from_hex
from .model import SchunkModel

_INST = re.compile(r"0x[0-9A-F]{4}\Z")
MAX_HEADER = 16384
MAX_BODY = 65536


class HttpError(ValueError):
    """Bytes that are no HTTP request: the session answers 400 and drops what it had."""


@dataclass(frozen=True)
class Request:
    method: str
    target: str
    headers: dict[str, str]
    body: bytes


class RequestParser:
    """HTTP/1.1 requests from a byte stream, one connection's worth (pipelined requests come out in order)."""

    def __init__(self) -> None:
        self.buffer = bytearray()

    def feed(self, data: bytes) -> list[Request]:
        self.buffer += data
        out: list[Request] = []
        while True:
            end = self.buffer.find(b"\r\n\r\n")
            if end < 0:
                if len(self.buffer) > MAX_HEADER:
                    self.buffer.clear()
                    raise HttpError("request header too long")
                return out
            head = bytes(self.buffer[:end]).decode("latin-1")
            lines = head.split("\r\n")
            parts = lines[0].split(" ")
            if len(parts) != 3 or not parts[2].startswith("HTTP/1."):
                self.buffer.clear()
                raise HttpError(f"bad request line {lines[0][:60]!r}")
            headers: dict[str, str] = {}
            for line in lines[1:]:
                name, colon, value = line.partition(":")
                if not colon:
                    self.buffer.clear()
                    raise HttpError(f"bad header line {line[:60]!r}")
                headers[name.strip().lower()] = value.strip()
            try:
                length = int(headers.get("content-length", "0"))
            except ValueError:
                self.buffer.clear()
                raise HttpError("bad Content-Length") from None
            if not 0 <= length <= MAX_BODY:
                self.buffer.clear()
                raise HttpError("body too long")
            if len(self.buffer) < end + 4 + length:
                return out
            body = bytes(self.buffer[end + 4 : end + 4 + length])
            del self.buffer[: end + 4 + length]
            out.append(Request(parts[0].upper(), parts[1], headers, body))


def response(status: int, payload: object, reason: str = "") -> bytes:
    body = json.dumps(payload, separators=(",", ":")).encode() if payload is not None else b""
    reasons = {200: "OK", 400: "Bad Request", 404: "Not Found", 405: "Method Not Allowed", 503: "Unavailable"}
    head = (
        f"HTTP/1.1 {status} {reason or reasons.get(status, 'Status')}\r\n"
        "Content-Type: application/json\r\n"
        f"Content-Length: {len(body)}\r\n\r\n"
    )
    return head.encode() + body


class WebSession:
    """One HTTP connection to the unit (a kit ``DeviceSession``): requests in, one response each out."""

    def __init__(self, model: SchunkModel, unreachable_until: list[float]) -> None:
        self.model = model
        self.parser = RequestParser()
        self.unreachable_until = unreachable_until  # shared by every connection to the same unit

    def feed(self, data: bytes, now: float) -> list[bytes]:
        try:
            requests = self.parser.feed(data)
        except HttpError:
            return [response(400, {"error": "bad request"})]
        return [self.answer(r, now) for r in requests]

    def answer(self, request: Request, now: float) -> bytes:
        path, query = web_target(request.target)
        if path == "/adi/data.json" and request.method == "GET":
            if now < self.unreachable_until[0]:
                return response(503, {"detail": "Service Unavailable"})
            return response(200, self.get(query, now))
        if path == "/adi/update.json" and request.method == "POST":
            form = web_fields(request.body.decode("latin-1"), request.target)
            if "inst" not in form or "value" not in form:
                return response(422, {"detail": "inst and value are required"}, "Unprocessable Entity")
            return response(200, {"result": self.update(form["inst"], form["value"], now)})
        if path == "/adi/events.json" and request.method == "POST":
            try:
                events = json.loads(request.body or b"{}")
                seconds = float(events.get("lose_connection_sec", 0))
            except (ValueError, AttributeError, TypeError):
                return response(422, {"detail": "events: a JSON object"}, "Unprocessable Entity")
            if seconds > 0:
                self.unreachable_until[0] = now + seconds
            return response(200, True)
        if path in ("/adi/data.json", "/adi/update.json", "/adi/events.json"):
            return response(405, {"detail": "Method Not Allowed"})
        return response(404, {"detail": "Not Found"})

    def get(self, query: dict[str, str], now: float) -> list[str]:
        if "inst" not in query or "count" not in query:
            return []
        inst, count = query["inst"], query["count"]
        if count != "1" or not _INST.match(inst):
            return []
        data = self.model.read(int(inst, 16), now)
        if data is None:
            return []
        if PARAMETERS[int(inst, 16)].kind in (Kind.ENUM, Kind.BOOL):
            data = data[:1]  # one byte, as the units answer (the dummy's configs: ["0B"], ["D9"])
        return [data.hex().upper()]

    def update(self, inst: str, value: str, now: float) -> int:
        if not _INST.match(inst) or int(inst, 16) not in PARAMETERS:
            return 1
        try:
            data = from_hex(value)
        except ValueError:
            return 1
        return 0 if self.model.write(int(inst, 16), data, now) else 1

    def closed(self, now: float) -> None:
        """A dropped connection changes nothing on the unit."""
