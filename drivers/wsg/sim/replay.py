"""``grippers sim wsg --replay FILE``: the WSG over TCP answering as a captured session did (drivers/replay.py
has the rules), so a capture from a real gripper becomes a regression fixture."""

from __future__ import annotations

import socket
import threading

from ...captures import FROM_DEVICE, TO_DEVICE, parse_hex_dump
from ...inet import tcp_listener
from ...replay import Mismatch, Script, Step, relative, report
from ...simkit import Sender
from .. import commands
from ..protocol import Packet, PacketParser


def wsg_script(blob: bytes, name: str) -> Script:
    """Steps of a WSG byte capture (hex dump with directions); each packet reassembled per direction."""
    parsers = {TO_DEVICE: PacketParser(), FROM_DEVICE: PacketParser()}
    steps: list[Step] = []
    for chunk in parse_hex_dump(blob.decode("ascii", errors="replace").splitlines()):
        if chunk.direction not in parsers:
            raise ValueError(f"{name}: line {chunk.line} has no direction (> or <); a replay needs both")
        for item in parsers[chunk.direction].feed(chunk.data):
            if not isinstance(item, Packet):
                continue  # noise in the capture is not replayed
            raw = item.encode()
            if chunk.direction == TO_DEVICE:
                shown = f"{commands.describe(item, 'request')} [{raw.hex()}]"
                steps.append(Step(raw, shown, []))
                steps[-1].answers.append((chunk.timestamp or 0.0, None))  # the request's time, removed below
            elif steps:
                steps[-1].answers.append((chunk.timestamp or 0.0, raw))
    return Script(relative(steps))


class WsgReplayServer:
    """The WSG over TCP, answering from a script; one connection at a time continues the same script."""

    def __init__(self, script: Script, host: str, port: int, time_scale: float = 1.0) -> None:
        self.script = script
        self._sender = Sender(time_scale)
        self._listener = tcp_listener(host, port)
        self._listener.settimeout(0.05)  # close() alone does not wake a blocked accept() on Linux
        self._closed = threading.Event()
        self._lock = threading.Lock()
        self._conns: list[socket.socket] = []
        self._thread = threading.Thread(target=self._accept, name="wsg replay", daemon=True)
        self._thread.start()

    @property
    def url(self) -> str:
        host, port = self._listener.getsockname()[:2]
        return f"wsg+tcp://{host}:{port}"

    def _accept(self) -> None:
        while not self._closed.is_set():
            try:
                conn, _ = self._listener.accept()
            except TimeoutError:
                continue
            except OSError:
                return
            conn.settimeout(None)
            with self._lock:
                self._conns.append(conn)
            threading.Thread(target=self._serve, args=(conn,), daemon=True).start()

    def _serve(self, conn: socket.socket) -> None:
        parser = PacketParser()
        with conn:
            while not self._closed.is_set():
                try:
                    data = conn.recv(4096)
                except OSError:
                    return
                if not data:
                    return
                for item in parser.feed(data):
                    if not isinstance(item, Packet):
                        continue
                    raw = item.encode()
                    shown = f"{commands.describe(item, 'request')} [{raw.hex()}]"
                    with self._lock:
                        outcome = self.script.answer(raw, shown)
                    if isinstance(outcome, Mismatch):
                        report(outcome)
                    else:
                        self._sender.schedule(outcome, conn.sendall)

    def close(self) -> None:
        self._closed.set()
        self._sender.close()
        self._listener.close()
        with self._lock:
            for conn in self._conns:
                try:
                    conn.shutdown(socket.SHUT_RDWR)
                except OSError:
                    pass
                conn.close()
        self._thread.join(2)
