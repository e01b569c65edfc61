"""Fixtures for the UART tests: a pseudo-terminal whose far end a test scripts with exact firmware lines,
and the UART simulator on a pseudo-terminal.

The scripted far end is a thread that reads what the client writes to the pty and answers each complete
command line through a function the test gives, so the client is tested against real bytes on a real tty
without our simulator in between.
"""

from __future__ import annotations

import os
import select
import threading
import tty
from collections.abc import Callable, Iterator

import pytest

from ...closing import closed_after

Script = Callable[[bytes], bytes | None]


class ScriptedPty:
    """The master side of a pty: answers each ``...\\n`` line it receives with ``script(line)``."""

    def __init__(self, script: Script) -> None:
        self.script = script
        self.master, self.slave = os.openpty()
        tty.setraw(self.slave)
        self.path = os.ttyname(self.slave)
        self.received: list[bytes] = []
        self._stop = threading.Event()
        self._thread = threading.Thread(target=self._run, name="scripted-pty", daemon=True)
        self._thread.start()

    def _run(self) -> None:
        buf = b""
        while not self._stop.is_set():
            ready, _, _ = select.select([self.master], [], [], 0.02)
            if not ready:
                continue
            try:
                data = os.read(self.master, 4096)
            except OSError:
                return
            buf += data
            while b"\n" in buf:
                line, buf = buf.split(b"\n", 1)
                line += b"\n"
                self.received.append(line)
                answer = self.script(line)
                if answer:
                    os.write(self.master, answer)

    def write(self, data: bytes) -> None:
        os.write(self.master, data)

    def close_master(self) -> None:
        """Make the port disappear under the client."""
        self._stop.set()
        self._thread.join(2)
        for fd in (self.master, self.slave):
            try:
                os.close(fd)
            except OSError:
                pass

    def close(self) -> None:
        self.close_master()


@pytest.fixture
def scripted_pty() -> Iterator[Callable[[Script], ScriptedPty]]:
    with closed_after(ScriptedPty) as make:
        yield make


@pytest.fixture
def msg_sim():
    """The UART simulator of one MSG gripper on a pty, 200x faster than real time."""
    from grippers.drivers.stepfoc.sim.model import MsgModel
    from grippers.drivers.stepfoc.sim.uart_server import serve_uart

    def make(model: MsgModel | None = None, **kw):
        kw.setdefault("time_scale", 200.0)
        return serve_uart(model or MsgModel(), "pty", **kw)

    with closed_after(make) as started:
        yield started
