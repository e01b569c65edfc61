"""Byte links: one small interface over a serial line (pyserial) and a TCP connection, for every driver.

Every family's client used to write its own: open a port or a socket, send a request, read until the codec
returns a frame within a deadline, tell silence (a timeout) from a broken line, remember that the line broke,
and open a fresh one on reconnection. Those copies drifted (one forgot the deadline on a partial frame, one
kept a late reply that then answered the next request). This module is the one place for it:

- :class:`ByteLink` is what a client holds: :meth:`~ByteLink.write`, :meth:`~ByteLink.read` (what arrived
  within a wait), :meth:`~ByteLink.read_exactly`, :meth:`~ByteLink.read_until`,
  :meth:`~ByteLink.read_decoded` (bytes fed to a sans-IO codec until it yields), :meth:`~ByteLink.exchange`
  (write a request and read its reply, one caller at a time), :meth:`~ByteLink.discard_input`, and
  :meth:`~ByteLink.close` (idempotent). Every read has a finite deadline and raises
  :class:`~grippers.drivers.errors.GripperTimeout` when it passes; a line that broke (end of file, a reset
  connection, a serial error) raises :class:`~grippers.drivers.errors.ConnectionLost` and sets :attr:`lost`
  for good. Both name the device and the command.
- :class:`SerialLink` and :class:`TcpLink` are the two transports; :func:`open_link` picks one from an
  address (``tcp://HOST:PORT``, ``serial:///dev/ttyUSB0?baudrate=9600``, a family URL such as
  ``acme+tcp://HOST``, a device path or any pyserial URL). Another transport subclasses :class:`ByteLink`
  and fills three methods: ``_send``, ``_recv`` and ``_close``.
- :class:`LinkHolder` is swap-on-reconnect: it holds the current link (or a client over one), and
  :meth:`LinkHolder.reconnect` replaces a broken one with a fresh one that passed a check, atomically.

The drivers layer: nothing here imports :mod:`grippers` (the API); :mod:`grippers.kit` re-exports it for
plugin authors (docs/backend-kit.md).
"""

from __future__ import annotations

import contextlib
import socket
import threading
import time
from collections.abc import Callable, Sequence
from typing import Any, Generic, Protocol, TypeVar

from .closing import Closing
from .errors import ConnectionLost, GripperError, GripperTimeout, ProtocolError, URLError
from .serial_ports import open_serial_port
from .urls import ConnectionURL, format_host, parse_url, scheme_of, to_int

__all__ = [
    "ByteLink",
    "LinkHolder",
    "Reconnectable",
    "SerialLink",
    "TcpLink",
    "TraceFn",
    "open_link",
]

T = TypeVar("T")
TraceFn = Callable[[str, bytes], None]  # ("tx" | "rx", bytes): for -vv, the monitor, a benchmark's count

DEFAULT_TIMEOUT = 0.5  # seconds a read waits when the caller gives no deadline
DEFAULT_BAUDRATE = 115200
_CHUNK = 65536


class ByteLink(Closing):
    """A bidirectional byte stream with bounded reads and a lost flag; subclasses move the bytes.

    A subclass implements ``_send(data)`` (raise on failure), ``_recv(timeout)`` (the bytes that arrived
    within ``timeout`` seconds, ``b""`` for none; raise :class:`EOFError` when the peer closed the line,
    anything else when it failed) and ``_close()``. The base class turns their failures into
    :class:`ConnectionLost`, sets :attr:`lost`, keeps bytes a read did not consume for the next one, and
    bounds every read.

    One thread may write while another reads (a reader thread and its callers); two concurrent readers
    must take turns through :attr:`lock` (:meth:`exchange` does).
    """

    kind = "link"  # "serial", "tcp": how messages name the transport

    def __init__(self, device: str, *, timeout: float = DEFAULT_TIMEOUT) -> None:
        if not timeout > 0:
            raise ValueError(f"timeout must be positive, not {timeout!r}")
        self.device = device
        self.timeout = float(timeout)
        self.trace: TraceFn | None = None
        self.last_rx = 0.0  # time.monotonic() of the last bytes received (a serial line's inter-frame gap)
        self.lock = threading.RLock()  # one exchange at a time (exchange() holds it)
        self._buf = bytearray()
        self._lost: ConnectionLost | None = None
        self._closed = False

    # -- state ---------------------------------------------------------------------------------------------

    @property
    def lost(self) -> bool:
        """True once the line broke (end of file, reset, serial error); stays true. Not set by close()."""
        return self._lost is not None

    @property
    def lost_reason(self) -> ConnectionLost | None:
        return self._lost

    @property
    def closed(self) -> bool:
        return self._closed

    @property
    def alive(self) -> bool:
        """Neither lost nor closed: a read or write may still succeed."""
        return self._lost is None and not self._closed

    def _down(self, command: str) -> ConnectionLost | None:
        if self._closed:
            return ConnectionLost("the link is closed", device=self.device, command=command)
        if self._lost is not None:
            return ConnectionLost(
                f"the link is down ({self._lost.message})", device=self.device, command=command
            )
        return None

    def _broke(self, message: str, command: str, exc: BaseException | None = None) -> ConnectionLost:
        """The line failed: remember it (unless we closed it ourselves) and return the error to raise."""
        if self._closed:
            return ConnectionLost("the link is closed", device=self.device, command=command)
        lost = ConnectionLost(message, device=self.device, command=command)
        if self._lost is None:
            self._lost = lost
        return lost

    # -- writing and reading ---------------------------------------------------------------------------------

    def write(self, data: bytes, *, command: str = "write") -> None:
        down = self._down(command)
        if down is not None:
            raise down
        try:
            self._send(data)
        except Exception as exc:  # noqa: BLE001 - pyserial: SerialException, OSError, termios.error, TypeError
            raise self._broke(f"{self.kind} write failed: {exc}", command, exc) from exc
        if self.trace is not None:
            self.trace("tx", data)

    def _pull(self, timeout: float, command: str) -> bytes:
        """One receive of at most ``timeout`` seconds from the transport (not the buffer)."""
        down = self._down(command)
        if down is not None:
            raise down
        try:
            data = self._recv(max(timeout, 0.0))
        except EOFError as exc:
            raise self._broke(f"the peer closed the {self.kind} connection", command, exc) from None
        except Exception as exc:  # noqa: BLE001 - see write()
            raise self._broke(f"{self.kind} read failed: {exc}", command, exc) from exc
        if data:
            self.last_rx = time.monotonic()
            if self.trace is not None:
                self.trace("rx", data)
        return data

    def read(self, timeout: float | None = None, *, command: str = "read") -> bytes:
        """What arrived within ``timeout`` seconds (the link's :attr:`timeout` if None): ``b""`` for nothing.

        Never raises on silence (a reader loop tells silence from failure this way); raises
        :class:`ConnectionLost` when the line broke."""
        if self._buf:
            data = bytes(self._buf)
            self._buf.clear()
            return data
        return self._pull(self.timeout if timeout is None else timeout, command)

    def _deadline(self, deadline: float | None) -> float:
        return time.monotonic() + self.timeout if deadline is None else deadline

    def _wait_more(self, deadline: float, started: float, command: str, what: str) -> None:
        """Receive into the buffer until something arrives; GripperTimeout once ``deadline`` passed."""
        while True:
            left = deadline - time.monotonic()
            if left <= 0:
                raise GripperTimeout(
                    f"no {what} within {max(deadline - started, 0.0):.3g} s",
                    device=self.device,
                    command=command,
                )
            data = self._pull(left, command)
            if data:
                self._buf += data
                return

    def read_exactly(self, n: int, deadline: float | None = None, *, command: str = "read") -> bytes:
        """``n`` bytes, by ``deadline`` (a :func:`time.monotonic` instant; None: :attr:`timeout` from now)."""
        started, deadline = time.monotonic(), self._deadline(deadline)
        while len(self._buf) < n:
            self._wait_more(deadline, started, command, f"{n} bytes (got {len(self._buf)})")
        data = bytes(self._buf[:n])
        del self._buf[:n]
        return data

    def read_until(
        self,
        terminator: bytes = b"\n",
        deadline: float | None = None,
        *,
        command: str = "read",
        limit: int = _CHUNK,
    ) -> bytes:
        """Bytes up to and including ``terminator``, by ``deadline``; :class:`ProtocolError` when ``limit``
        bytes came without one (the buffer is dropped: a line that long is not the device's)."""
        if not terminator:
            raise ValueError("read_until needs a terminator")
        started, deadline = time.monotonic(), self._deadline(deadline)
        while True:
            end = self._buf.find(terminator)
            if end >= 0:
                end += len(terminator)
                data = bytes(self._buf[:end])
                del self._buf[:end]
                return data
            if len(self._buf) > limit:
                head = bytes(self._buf[:40])
                self._buf.clear()
                raise ProtocolError(
                    f"no {terminator!r} after {limit} bytes ({head!r}...)",
                    device=self.device,
                    command=command,
                )
            self._wait_more(deadline, started, command, f"end of line {terminator!r}")

    def read_decoded(
        self, feed: Callable[[bytes], Sequence[T]], deadline: float | None = None, *, command: str = "read"
    ) -> Sequence[T]:
        """Feed what arrives to a sans-IO codec's ``feed(bytes) -> [messages]`` until it returns at least one
        message, by ``deadline``; the messages are returned (all of them: the codec consumed those bytes).

        A codec that raises :class:`ValueError` (a bad checksum, a line that is not the protocol's) becomes
        :class:`ProtocolError` naming the device and the command."""
        started, deadline = time.monotonic(), self._deadline(deadline)
        while True:
            if self._buf:
                data = bytes(self._buf)
                self._buf.clear()
                try:
                    out = feed(data)
                except GripperError:
                    raise
                except ValueError as exc:
                    raise ProtocolError(str(exc), device=self.device, command=command) from None
                if out:
                    return out
            self._wait_more(deadline, started, command, "complete reply")

    def exchange(
        self,
        request: bytes,
        feed: Callable[[bytes], Sequence[T]],
        *,
        command: str,
        timeout: float | None = None,
    ) -> Sequence[T]:
        """Write ``request`` and return what :meth:`read_decoded` decodes of its reply within ``timeout``
        (the link's :attr:`timeout` if None), holding :attr:`lock` so concurrent callers take turns."""
        with self.lock:
            self.write(request, command=command)
            return self.read_decoded(
                feed, time.monotonic() + (self.timeout if timeout is None else timeout), command=command
            )

    def discard_input(self) -> int:
        """Drop what is buffered or already waiting (a late reply of an exchange that timed out, which must
        not answer the next request); returns how many bytes were dropped. Never waits."""
        dropped = len(self._buf)
        self._buf.clear()
        while self.alive:
            data = self._pull(0.0, "discard")
            if not data:
                break
            dropped += len(data)
        return dropped

    def close(self) -> None:
        """Release the port or socket; idempotent. Reads and writes afterwards raise ConnectionLost."""
        if self._closed:
            return
        self._closed = True
        with contextlib.suppress(Exception):
            self._close()

    def __repr__(self) -> str:
        state = "closed" if self._closed else "lost" if self._lost else "open"
        return f"{type(self).__name__}({self.device!r}, {state})"

    # -- what a transport fills in ------------------------------------------------------------------------

    def _send(self, data: bytes) -> None:
        raise NotImplementedError

    def _recv(self, timeout: float) -> bytes:
        raise NotImplementedError

    def _close(self) -> None:
        raise NotImplementedError


class SerialLink(ByteLink):
    """A serial port, or anything :func:`serial.serial_for_url` opens (``/dev/ttyUSB0``, ``COM3``,
    ``loop://``, ``socket://HOST:PORT``, ``rfc2217://``), 8 data bits, no parity, 1 stop bit by default."""

    kind = "serial"

    def __init__(
        self,
        port: str,
        baudrate: int = DEFAULT_BAUDRATE,
        *,
        device: str | None = None,
        timeout: float = DEFAULT_TIMEOUT,
        **options: Any,
    ) -> None:
        super().__init__(device or port, timeout=timeout)
        self.port, self.baudrate = port, baudrate
        options.setdefault("bytesize", 8)
        options.setdefault("parity", "N")
        options.setdefault("stopbits", 1)
        self._port = (
            open_serial_port(  # exclusively: a second process is told "busy" (drivers/serial_ports.py)
                port,
                device=self.device,
                baudrate=baudrate,
                timeout=0.0,
                write_timeout=max(self.timeout, 1.0),
                **options,
            )
        )
        self._read_timeout = 0.0

    def _send(self, data: bytes) -> None:
        self._port.write(data)

    def _recv(self, timeout: float) -> bytes:
        if timeout != self._read_timeout:
            self._port.timeout = timeout
            self._read_timeout = timeout
        first = self._port.read(1)  # waits up to timeout for the first byte only
        if not first:
            return b""
        waiting = self._port.in_waiting
        return first + (self._port.read(waiting) if waiting else b"")

    def _close(self) -> None:
        self._port.close()


class TcpLink(ByteLink):
    """A TCP connection (TCP_NODELAY: requests are small and a reply is awaited)."""

    kind = "tcp"

    def __init__(
        self,
        host: str,
        port: int,
        *,
        device: str | None = None,
        timeout: float = DEFAULT_TIMEOUT,
        connect_timeout: float | None = None,
    ) -> None:
        super().__init__(device or f"tcp://{format_host(host, port)}", timeout=timeout)
        self.host, self.port = host, port
        try:
            self._sock = socket.create_connection((host, port), timeout=connect_timeout or max(timeout, 1.0))
        except OSError as exc:
            raise ConnectionLost(
                f"cannot connect to {format_host(host, port)}: {exc}", device=self.device, command="open"
            ) from exc
        self._sock.setsockopt(socket.IPPROTO_TCP, socket.TCP_NODELAY, 1)
        self._read_timeout: float | None = None

    def _send(self, data: bytes) -> None:
        self._sock.sendall(data)

    def _recv(self, timeout: float) -> bytes:
        timeout = max(
            timeout, 1e-4
        )  # 0 would make the socket non-blocking: BlockingIOError instead of silence
        if timeout != self._read_timeout:
            self._sock.settimeout(timeout)
            self._read_timeout = timeout
        try:
            data = self._sock.recv(_CHUNK)
        except TimeoutError:
            return b""
        if not data:
            raise EOFError
        return data

    def _close(self) -> None:
        with contextlib.suppress(OSError):
            self._sock.shutdown(socket.SHUT_RDWR)  # wakes a reader blocked in recv() on another thread
        self._sock.close()


def open_link(
    address: str | ConnectionURL,
    *,
    device: str | None = None,
    timeout: float = DEFAULT_TIMEOUT,
    default_port: int | None = None,
    baudrate: int = DEFAULT_BAUDRATE,
) -> ByteLink:
    """A link to ``address``:

    - ``tcp://HOST[:PORT]`` or ``FAMILY+tcp://HOST[:PORT]`` (the port defaults to ``default_port``);
    - ``serial://PORT[?baudrate=N]`` or ``FAMILY+serial://PORT[?baudrate=N]`` (PORT a device path or a
      pyserial URL);
    - anything else without a ``FAMILY+`` scheme is given to pyserial as it is (``/dev/ttyUSB0``, ``COM3``,
      ``loop://``, ``socket://HOST:PORT``).

    The URL grammar is the library's (drivers/urls.py); query parameters other than ``baudrate`` are the
    caller's and left alone. ``device`` names the device in errors (default: the address)."""
    if isinstance(address, ConnectionURL):
        url: ConnectionURL | None = address
    else:
        scheme = scheme_of(address)
        url = (
            parse_url(address, bare_family="link")
            if scheme.endswith(("tcp", "serial", "udp", "can"))
            else None
        )
    if url is None:
        return SerialLink(str(address), baudrate, device=device, timeout=timeout)
    name = device or url.url
    if url.transport == "tcp":
        port = url.port or default_port
        if not url.host or not port:
            raise URLError(f"{url.url}: a TCP link needs HOST:PORT")
        return TcpLink(url.host, port, device=name, timeout=timeout)
    if url.transport == "serial" and url.serial_port:
        rate = to_int(url.params["baudrate"], "baudrate", url.url) if "baudrate" in url.params else baudrate
        return SerialLink(url.serial_port, rate, device=name, timeout=timeout)
    raise URLError(f"{url.url}: a byte link runs over tcp or serial, not {url.transport!r}")


class Reconnectable(Protocol):
    """What :class:`LinkHolder` holds: a link, or a client over one, that says whether it still works."""

    @property
    def alive(self) -> bool: ...

    def close(self) -> None: ...


L = TypeVar("L", bound=Reconnectable)


class LinkHolder(Closing, Generic[L]):
    """The current link (or client) of a device, replaced by a fresh one on reconnection.

    ``connect()`` opens a new one; ``check(new)`` proves the device answers on it (a status read) before it
    is used, and a new one that fails its check is closed again. :meth:`reconnect` swaps under a lock, so a
    caller sees the old link or the new one, never a half-opened one, and two reconnections do not race.
    ``reuse_alive``: keep a link that never broke when its check passes (a serial line stays open while the
    device is silent: the device answering again is the reconnection).
    """

    def __init__(
        self,
        connect: Callable[[], L],
        *,
        check: Callable[[L], object] | None = None,
        link: L | None = None,
        reuse_alive: bool = False,
    ) -> None:
        self._connect, self._check, self.reuse_alive = connect, check, reuse_alive
        self._lock = threading.Lock()
        self._closed = False
        self._link: L = link if link is not None else self._open()

    @property
    def link(self) -> L:
        return self._link

    @property
    def alive(self) -> bool:
        return not self._closed and self._link.alive

    def _open(self) -> L:
        new = self._connect()
        if self._check is not None:
            try:
                self._check(new)
            except BaseException:
                new.close()
                raise
        return new

    def swap(self, new: L) -> L:
        """Put ``new`` in place and return the old one (not closed: the caller decides)."""
        with self._lock:
            old, self._link = self._link, new
        return old

    def reconnect(self) -> L:
        """A working link: the current one if ``reuse_alive`` and it passes the check, else a fresh one
        (the broken one is closed first: a serial port must be free before it is opened again)."""
        with self._lock:
            if self._closed:
                device = getattr(self._link, "device", None)
                raise ConnectionLost("the holder is closed", device=device, command="reconnect")
            old = self._link
            if self.reuse_alive and old.alive:
                if self._check is not None:
                    self._check(old)
                return old
            old.close()
            self._link = self._open()
            return self._link

    def close(self) -> None:
        with self._lock:
            self._closed = True
            link = self._link
        link.close()
