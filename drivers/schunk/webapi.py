"""The unit's web API as a parameter link: one instance read or written per HTTP request, on the standard
library's ``http.client`` (a kept-alive connection, a finite timeout on every socket operation).

The request forms are those SCHUNK's driver sends (schunk_gripper_library/driver.py): ``GET
/adi/data.json?inst=0x0040&count=1`` answers ``["HEX"]``; ``POST /adi/update.json`` with the form fields
``inst`` and ``value`` (upper-case hex) writes one; a bare ``GET /adi/data.json`` answering 2xx says a unit
is there. Errors are the library's: silence is :class:`GripperTimeout`, a refused or dropped connection and
an HTTP 503 (the unit unreachable behind its web server) are :class:`ConnectionLost`, an instance the unit
does not have or a refused write is :class:`CommandFailed`, an answer that is not the API's is
:class:`ProtocolError`; each names the device and the command.
"""

from __future__ import annotations

import http.client
import json
import threading
from collections.abc import Callable

from ..errors import CommandFailed, ConnectionLost, GripperTimeout, ProtocolError
from ..urls import encode_query
from .protocol import CodecError, from_hex, inst_text, padded, parameter

Trace = Callable[[str, bytes], None]


_READ_PATHS: dict[int, str] = {}  # inst -> the GET's path: built once, a poll is one lookup


class WebLink:
    """Reads and writes of parameters over HTTP. Thread-safe: one request at a time on the connection."""

    def __init__(
        self, host: str, port: int, *, device: str, timeout: float, trace: Trace | None = None
    ) -> None:
        self.host, self.port, self.device, self.timeout = host, port, device, timeout
        self.lock = threading.Lock()
        self.lost = False
        self.closed = False
        self.trace = trace
        self._conn: http.client.HTTPConnection | None = None

    @property
    def alive(self) -> bool:
        return not (self.lost or self.closed)

    def _connection(self) -> http.client.HTTPConnection:
        if self._conn is None:
            self._conn = http.client.HTTPConnection(self.host, self.port, timeout=self.timeout)
        return self._conn

    def _drop(self) -> None:
        if self._conn is not None:
            self._conn.close()
            self._conn = None

    def request(self, method: str, path: str, body: bytes | None, command: str) -> tuple[int, bytes]:
        """One request and its whole response (status, body); the connection is kept for the next one."""
        if self.closed:
            raise ConnectionLost("the link is closed", device=self.device, command=command)
        headers = {"Content-Type": "application/x-www-form-urlencoded"} if body is not None else {}
        with self.lock:
            for attempt in (0, 1):
                conn = self._connection()
                fresh = conn.sock is None
                try:
                    if self.trace is not None:
                        self.trace("tx", f"{method} {path}".encode() + (b" " + body if body else b""))
                    conn.request(method, path, body=body, headers=headers)
                    reply = conn.getresponse()
                    data = reply.read()
                except TimeoutError:
                    self._drop()
                    raise GripperTimeout(
                        f"no HTTP answer within {self.timeout:g} s ({method} {path})",
                        device=self.device,
                        command=command,
                    ) from None
                except (http.client.RemoteDisconnected, BrokenPipeError, ConnectionResetError) as exc:
                    self._drop()
                    if attempt == 0 and not fresh:
                        continue  # a kept-alive connection the server had closed: one fresh try
                    self.lost = True
                    raise ConnectionLost(
                        f"HTTP connection lost ({exc})", device=self.device, command=command
                    ) from None
                except (OSError, http.client.HTTPException) as exc:
                    self._drop()
                    self.lost = True
                    raise ConnectionLost(
                        f"HTTP {self.host}:{self.port}: {type(exc).__name__}: {exc}",
                        device=self.device,
                        command=command,
                    ) from None
                if self.trace is not None:
                    self.trace("rx", f"{reply.status} ".encode() + data)
                if reply.will_close:
                    self._drop()
                self.lost = False
                return reply.status, data
        raise AssertionError("unreachable")

    def probe(self, command: str = "open") -> None:
        """What SCHUNK's driver does to find a unit: a bare ``GET /adi/data.json`` answering 2xx."""
        status, _ = self.request("GET", "/adi/data.json", None, command)
        self._status(status, command)

    def _status(self, status: int, command: str) -> None:
        if status == 503:
            self.lost = True
            raise ConnectionLost("the unit is unreachable (HTTP 503)", device=self.device, command=command)
        if not 200 <= status < 300:
            raise ProtocolError(f"HTTP {status} from the web API", device=self.device, command=command)

    def read(self, inst: int, command: str) -> bytes:
        """The instance's bytes, padded to the parameter's size as SCHUNK's driver pads them."""
        path = _READ_PATHS.get(inst) or _READ_PATHS.setdefault(
            inst, f"/adi/data.json?{encode_query({'inst': inst_text(inst), 'count': '1'})}"
        )
        status, data = self.request("GET", path, None, command)
        self._status(status, command)
        try:
            values = json.loads(data)
        except ValueError:
            raise ProtocolError(
                f"{inst_text(inst)}: not JSON: {data[:60]!r}", device=self.device, command=command
            ) from None
        if values == []:
            raise CommandFailed(
                f"the unit has no parameter {inst_text(inst)} ({parameter(inst).name})",
                device=self.device,
                command=command,
            )
        if not isinstance(values, list) or not values or not isinstance(values[0], str):
            raise ProtocolError(
                f"{inst_text(inst)}: unexpected {data[:60]!r}", device=self.device, command=command
            )
        try:
            return padded(inst, from_hex(values[0]))
        except CodecError as exc:
            raise ProtocolError(str(exc), device=self.device, command=command) from None

    def write(self, inst: int, data: bytes, command: str) -> None:
        body = encode_query({"inst": inst_text(inst), "value": data.hex().upper()}).encode()
        status, reply = self.request("POST", "/adi/update.json", body, command)
        self._status(status, command)
        try:
            result = json.loads(reply).get("result")
        except (ValueError, AttributeError):
            raise ProtocolError(
                f"update: unexpected {reply[:60]!r}", device=self.device, command=command
            ) from None
        if result != 0:
            raise CommandFailed(
                f"the unit refused the write of {inst_text(inst)} (result {result})",
                device=self.device,
                command=command,
            )

    def close(self) -> None:
        with self.lock:
            self.closed = True
            self._drop()
