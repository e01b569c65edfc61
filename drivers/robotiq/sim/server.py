"""Servers around :class:`~.model.RobotiqModel`: a pty for the RTU line (as an RS-485 adapter's
/dev/ttyUSB0) and TCP carrying the same raw RTU frames (as a UR robot's tool-communication forwarder).

One thread per server moves bytes: requests are parsed with the codec's :class:`RequestParser` (silent on
another slave id or a bad CRC, as the device is), answered by the model at the scaled clock's time, and passed
through the simkit's fault hooks (drop, delay, corrupt, truncate, duplicate, garbage, silence, close) like
every other simulator of the library. Tests that must not race the clock pause it (:meth:`pause`) and step
it (:meth:`step`).
"""

from __future__ import annotations

import contextlib
import functools
import os
import selectors
import socket
import threading
import time
import tty
from collections.abc import Callable
from typing import Any

from ...closing import Closing
from ...simkit import FaultHooks, SimClock, apply_fault, first_half, flip_last_byte
from ...urls import format_host
from .. import urcap
from ..modbus import READ_HOLDING, WRITE_MULTIPLE, Request, RequestParser
from ..registers import COMMAND_ADDRESS, STATUS_ADDRESS, Command
from .model import RobotiqModel

__all__ = ["RobotiqSimServer", "serve"]


class _Link:
    """One client: how to write to it, and what its bytes are (RTU requests, or URCap lines)."""

    def __init__(self, write: Callable[[bytes], None], name: str, *, urcap: bool = False) -> None:
        self.write = write
        self.name = name
        self.urcap = urcap
        self.parser = RequestParser(None)  # every slave id: the model answers its own, stays silent on others
        self.lines = bytearray()


class RobotiqSimServer(Closing):
    """A running simulator: ``.url``, ``.model``, ``.faults``, ``.clock``; ``close()`` stops it.

    Tests that change the model (``part_width_mm``, :meth:`RobotiqModel.inject_fault`) hold ``.lock``.
    """

    def __init__(
        self, model: RobotiqModel, listen: str, *, time_scale: float = 1.0, family: str = "robotiq"
    ) -> None:
        self.model = model
        self.clock = SimClock(time_scale)
        self.faults = FaultHooks()
        self.lock = threading.RLock()
        self.error: BaseException | None = None
        self._paused_at: float | None = None
        self._selector = selectors.DefaultSelector()
        self._wake_r, self._wake_w = socket.socketpair()
        self._wake_r.setblocking(False)
        self._selector.register(self._wake_r, selectors.EVENT_READ, None)
        self._links: dict[Any, _Link] = {}
        self._delayed: list[tuple[float, _Link, bytes]] = []
        self._closed = threading.Event()
        self._listener: socket.socket | None = None
        self._master = self._slave = -1
        if listen in ("pty", "serial"):
            self._open_pty(family)
        else:
            self._open_tcp(listen, family)
        self._thread = threading.Thread(target=self._run, name=f"robotiq-sim {self.url}", daemon=True)
        self._thread.start()

    # -- clock ---------------------------------------------------------------------------------------------

    def now(self) -> float:
        return self._paused_at if self._paused_at is not None else self.clock.now()

    def pause(self) -> None:
        """Hold the device still: simulated time stops until :meth:`resume` (or moves by :meth:`step`)."""
        with self.lock:
            if self._paused_at is None:
                self._paused_at = self.clock.now()

    def step(self, seconds: float) -> None:
        with self.lock:
            if self._paused_at is None:
                raise RuntimeError("step() needs a paused clock (pause() first)")
            self._paused_at += seconds
            self.model.advance(self._paused_at)

    def resume(self) -> None:
        with self.lock:
            if self._paused_at is not None:
                self.clock = SimClock(self.clock.time_scale, start=self._paused_at)
                self._paused_at = None

    # -- transports ----------------------------------------------------------------------------------------

    def _open_pty(self, family: str) -> None:
        self._master, self._slave = os.openpty()
        tty.setraw(self._slave)  # binary frames: no echo, no CR/LF translation
        os.set_blocking(self._master, False)
        self.path = os.ttyname(self._slave)
        self.url = f"{family}+serial://{self.path}"
        link = _Link(self._write_pty, f"pty {self.path}")
        self._links[self._master] = link
        self._selector.register(self._master, selectors.EVENT_READ, self._read_pty)

    def _write_pty(self, data: bytes) -> None:
        view = memoryview(data)
        while view:
            try:
                n = os.write(self._master, view)
            except BlockingIOError:
                return  # a UART with nobody listening loses bytes instead of blocking
            view = view[n:]

    def _read_pty(self) -> None:
        try:
            data = os.read(self._master, 65536)
        except (BlockingIOError, InterruptedError, OSError):
            return
        if data:
            self._received(self._links[self._master], data)

    def _open_tcp(self, listen: str, family: str) -> None:
        from ...urls import parse_url

        self._urcap = listen.startswith("urcap://")
        url = parse_url(
            "tcp://" + listen.partition("://")[2] if self._urcap else listen, bare_family=family, listen=True
        )
        host, port = url.host or "127.0.0.1", url.port or 0
        self._listener = socket.create_server((host, port))
        self._listener.setblocking(False)
        self.port = self._listener.getsockname()[1]
        self.url = f"{family}+tcp://{format_host(host, self.port)}"
        if self._urcap:
            self.url += "?protocol=urcap"
        self._selector.register(self._listener, selectors.EVENT_READ, self._accept)

    def _accept(self) -> None:
        assert self._listener is not None
        try:
            sock, peer = self._listener.accept()
        except OSError:
            return
        sock.setblocking(True)
        sock.setsockopt(socket.IPPROTO_TCP, socket.TCP_NODELAY, 1)
        link = _Link(functools.partial(self._send_tcp, sock), f"tcp {peer}", urcap=self._urcap)
        self._links[sock] = link
        self._selector.register(sock, selectors.EVENT_READ, functools.partial(self._read_tcp, sock))

    def _send_tcp(self, sock: socket.socket, data: bytes) -> None:
        with contextlib.suppress(OSError):
            sock.sendall(data)

    def _read_tcp(self, sock: socket.socket) -> None:
        try:
            data = sock.recv(65536)
        except OSError:
            data = b""
        if not data:
            self._drop(sock)
            return
        self._received(self._links[sock], data)

    def _drop(self, sock: Any) -> None:
        self._links.pop(sock, None)
        with contextlib.suppress(KeyError, ValueError):
            self._selector.unregister(sock)
        with contextlib.suppress(OSError):
            sock.close()

    # -- the loop ------------------------------------------------------------------------------------------

    def _replies(self, link: _Link, data: bytes) -> list[bytes]:
        if link.urcap:
            return self._urcap_replies(link, data)
        out = []
        for req in link.parser.feed(data):
            with self.lock:
                reply = self.model.handle(req, self.now())
            if reply is not None:
                out.append(reply)
        return out

    def _urcap_replies(self, link: _Link, data: bytes) -> list[bytes]:
        """The URCap's socket in front of the same model: SET is a write of the request block, GET a read of
        the status (docs/protocols-robotiq.md §5). A line it does not understand gets no answer."""
        link.lines += data
        out = []
        while b"\n" in link.lines:
            raw, _, rest = bytes(link.lines).partition(b"\n")
            link.lines = bytearray(rest)
            try:
                verb, arg = urcap.parse_command(raw.decode("ascii", "replace"))
            except ValueError:
                continue
            with self.lock:
                now, slave = self.now(), self.model.p.slave
                if verb == "SET":
                    assert isinstance(arg, dict)
                    c = self.model.command
                    fields = {"ACT": c.act, "GTO": c.gto, "ATR": c.atr, "ARD": c.ard}
                    fields.update({k: bool(v) for k, v in arg.items() if k in fields})
                    cmd = Command(
                        act=fields["ACT"], gto=fields["GTO"], atr=fields["ATR"], ard=fields["ARD"],
                        position=arg.get("POS", c.position), speed=arg.get("SPE", c.speed),
                        force=arg.get("FOR", c.force),
                    )  # fmt: skip
                    req = Request(slave, WRITE_MULTIPLE, COMMAND_ADDRESS, 3, COMMAND_ADDRESS, cmd.registers())
                    self.model.handle(req, now)
                    out.append(b"ack\n")
                else:
                    self.model.handle(Request(slave, READ_HOLDING, STATUS_ADDRESS, 3), now)
                    st, c = self.model.status(), self.model.command
                    value = {
                        "ACT": int(st.act), "GTO": int(st.gto), "STA": int(st.sta), "OBJ": int(st.obj),
                        "FLT": st.fault, "PRE": st.position_echo, "POS": st.position, "SPE": c.speed,
                        "FOR": c.force,
                    }[str(arg)]  # fmt: skip
                    out.append(f"{arg} {value}\n".encode())
        return out

    def _received(self, link: _Link, data: bytes) -> None:
        for reply in self._replies(link, data):
            if self.faults.silent:
                continue
            reply = self.faults.take_garbage() + reply
            out, delay = apply_fault(reply, self.faults.take(), corrupt=flip_last_byte, truncate=first_half)
            for frame in out:
                if delay:
                    self._delayed.append((time.monotonic() + delay, link, frame))
                else:
                    link.write(frame)

    def _run(self) -> None:
        try:
            while not self._closed.is_set():
                wait = 0.05
                if self._delayed:
                    wait = max(0.0, min(wait, min(d[0] for d in self._delayed) - time.monotonic()))
                for key, _ in self._selector.select(wait):
                    if key.fileobj is self._wake_r:
                        with contextlib.suppress(OSError):
                            self._wake_r.recv(4096)
                    else:
                        key.data()
                now = time.monotonic()
                due = [d for d in self._delayed if d[0] <= now]
                self._delayed = [d for d in self._delayed if d[0] > now]
                for _, link, frame in due:
                    link.write(frame)
                if self.faults.close_requested.is_set():
                    self.faults.close_requested.clear()
                    for sock in [s for s in self._links if isinstance(s, socket.socket)]:
                        self._drop(sock)
                with self.lock:
                    self.model.advance(self.now())
        except BaseException as exc:  # noqa: BLE001 - reported by close() and the gripper_sim fixture
            self.error = exc

    def close(self) -> None:
        if self._closed.is_set():
            return
        self._closed.set()
        with contextlib.suppress(OSError):
            self._wake_w.send(b"\0")
        if self._thread is not threading.current_thread():
            self._thread.join(timeout=5.0)
        for sock in [s for s in self._links if isinstance(s, socket.socket)]:
            self._drop(sock)
        if self._listener is not None:
            self._listener.close()
        if self._master >= 0:
            os.close(self._master)
            os.close(self._slave)
        self._selector.close()
        self._wake_r.close()
        self._wake_w.close()


def serve(
    model: RobotiqModel, listen: str = "tcp://127.0.0.1:0", *, time_scale: float = 1.0
) -> RobotiqSimServer:
    """Start a simulator: ``listen`` is ``pty`` (the RTU line), ``tcp://HOST:PORT`` (a forwarder; port 0: any
    free port) or ``urcap://HOST:PORT`` (the URCap's ASCII socket in front of the same model)."""
    return RobotiqSimServer(model, listen, time_scale=time_scale)
