"""A ``grippers serve`` subprocess on a loopback port chosen at run time (port 0), and helpers.

The server always runs in its own process, as in a cell: what crosses is Zenoh on loopback, nothing else.
"""

from __future__ import annotations

import os
import re
import select
import signal
import subprocess
import sys
import time
from collections.abc import Callable, Iterator
from pathlib import Path

import pytest

from ..closing import closed_after

pytest.importorskip("zenoh")

ROOT = Path(__file__).resolve().parents[2]
START_TIMEOUT = 30.0
TIME_SCALE = 50


class ServeProcess:
    """``grippers serve ARGS --listen tcp/127.0.0.1:0``; ``urls`` maps each served name to its URL."""

    def __init__(self, *args: str, listen: str | None = "tcp/127.0.0.1:0") -> None:
        cmd = [sys.executable, "-m", "grippers", "serve", *args]
        if listen:
            cmd += ["--listen", listen]
        self.proc = subprocess.Popen(
            cmd,
            cwd=ROOT,
            stdout=subprocess.PIPE,
            stderr=subprocess.PIPE,
            text=True,
            env={**os.environ, "PYTHONUNBUFFERED": "1"},
        )
        self.urls: dict[str, str] = {}
        self.stderr_text = ""  # what the server wrote on stderr, read by close()
        self.expected = sum(1 for a in args if not a.startswith("-") and ("://" in a or "=" in a))
        self._read_urls()

    def _read_urls(self) -> None:
        assert self.proc.stdout is not None
        fd = self.proc.stdout.fileno()
        deadline = time.monotonic() + START_TIMEOUT
        seen = ""
        while time.monotonic() < deadline and len(self.urls) < self.expected:
            # os.read, not readline: a buffered reader would hide lines already read from select().
            ready, _, _ = select.select([fd], [], [], 0.2)
            if not ready:
                if self.proc.poll() is not None:
                    break
                continue
            chunk = os.read(fd, 65536).decode()
            if not chunk:
                break
            seen += chunk
            for m in re.finditer(r"^(\S+): .* serving at (\S+)$", seen, re.M):
                self.urls[m.group(1)] = m.group(2)
        if len(self.urls) < self.expected:
            self.proc.kill()
            self.proc.wait(5)
            err = self.proc.stderr.read() if self.proc.stderr else ""
            self.close()
            raise RuntimeError(f"grippers serve printed {seen!r}; stderr {err[-3000:]!r}")

    @property
    def endpoint(self) -> str:
        return next(iter(self.urls.values())).split("connect=", 1)[1]

    def close(self, sig: int = signal.SIGTERM) -> int | None:
        if self.proc.poll() is None:
            self.proc.send_signal(sig)
            try:
                self.proc.wait(15)
            except subprocess.TimeoutExpired:
                self.proc.kill()
                self.proc.wait(5)
        if self.proc.stderr and not self.proc.stderr.closed:
            self.stderr_text = self.proc.stderr.read()
        for stream in (self.proc.stdout, self.proc.stderr):
            if stream:
                stream.close()
        return self.proc.returncode


@pytest.fixture
def serve() -> Iterator[Callable[..., ServeProcess]]:
    with closed_after(ServeProcess) as start:
        yield start


def sim(profile: str, scale: float = TIME_SCALE, **params: object) -> str:
    query = "&".join([f"time_scale={scale}", *(f"{k}={v}" for k, v in params.items())])
    return f"sim://{profile}?{query}"
