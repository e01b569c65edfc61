"""The panel's tests: a real uvicorn server on loopback (grippers/panel/server.py) over simulators.

The tests in this folder without the ``browser`` marker speak HTTP and WebSocket themselves (httpx and the
``websockets`` client); the ``browser`` ones drive Debian's chromium with Playwright and run through
scripts/run-browser-tests.sh, which sets ``GRIPPERS_BROWSER_TESTS=1`` (without it they skip, naming the
script, as the ROS 2 tests do).
"""

from __future__ import annotations

import json
import time
from collections.abc import Callable, Iterator
from typing import Any

import pytest

pytest.importorskip("starlette", reason="the panel extra: pip install '.[panel]'")
pytest.importorskip("uvicorn", reason="the panel extra: pip install '.[panel]'")

import grippers
from grippers.panel.server import PanelServer


@pytest.fixture
def opened() -> Iterator[Callable[..., Any]]:
    """``opened(url)``: a gripper closed after the test."""
    grippers_: list[Any] = []

    def open_(url: str, **kwargs: Any) -> Any:
        g = grippers.open(url, **kwargs)
        grippers_.append(g)
        return g

    yield open_
    for g in reversed(grippers_):
        g.close()


@pytest.fixture
def serve() -> Iterator[Callable[..., PanelServer]]:
    """``serve({"left": g}, listen=..., token=...)``: a started panel, closed after the test."""
    servers: list[PanelServer] = []

    def start(named: dict[str, Any], **kwargs: Any) -> PanelServer:
        server = PanelServer(named, **kwargs).start()
        servers.append(server)
        return server

    yield start
    for s in servers:
        s.close()


def wait_for(predicate: Callable[[], Any], what: str, timeout: float = 10.0) -> Any:
    deadline = time.monotonic() + timeout
    while time.monotonic() < deadline:
        value = predicate()
        if value:
            return value
        time.sleep(0.02)
    raise AssertionError(f"{what}: not within {timeout:g} s")


class PageClient:
    """A page as the server sees it, without a browser: the WebSocket, commands and what comes back."""

    def __init__(self, server: PanelServer, **kwargs: Any) -> None:
        from websockets.sync.client import connect

        base = f"ws://127.0.0.1:{server.port}/ws"
        if server.token:
            kwargs.setdefault("additional_headers", {"Authorization": f"Bearer {server.token}"})
        self._connection = connect(base, **kwargs)
        self.ws = self._connection.__enter__()  # a context manager: closed in close()
        hello = json.loads(self.ws.recv(timeout=5))
        assert hello["type"] == "hello"
        self.page = hello["page"]
        self.label = hello["label"]
        self._next = 0
        self.snapshots: dict[str, dict[str, Any]] = {}
        self.done: list[dict[str, Any]] = []

    def _take(self, message: dict[str, Any]) -> None:
        if message["type"] == "update":
            for snap in message["grippers"]:
                self.snapshots[snap["name"]] = snap
        elif message["type"] == "done":
            self.done.append(message)

    def command(self, name: str, command: str, **args: Any) -> dict[str, Any]:
        """Send one command; its reply (other messages are kept on the way)."""
        self._next += 1
        self.ws.send(json.dumps({"id": self._next, "name": name, "command": command, "args": args}))
        return self.reply(self._next)

    def send_raw(self, text: str) -> None:
        self.ws.send(text)

    def reply(self, request_id: Any) -> dict[str, Any]:
        deadline = time.monotonic() + 10
        while time.monotonic() < deadline:
            message = json.loads(self.ws.recv(timeout=10))
            if message["type"] == "reply" and message.get("id") == request_id:
                return dict(message)
            self._take(message)
        raise AssertionError(f"no reply to {request_id}")

    def pump(self, seconds: float = 0.1) -> None:
        end = time.monotonic() + seconds
        while time.monotonic() < end:
            try:
                self._take(json.loads(self.ws.recv(timeout=max(0.01, end - time.monotonic()))))
            except TimeoutError:
                return

    def close(self) -> None:
        self._connection.__exit__(None, None, None)


@pytest.fixture
def page() -> Iterator[Callable[..., PageClient]]:
    pages: list[PageClient] = []

    def connect(server: PanelServer, **kwargs: Any) -> PageClient:
        p = PageClient(server, **kwargs)
        pages.append(p)
        return p

    yield connect
    for p in pages:
        try:
            p.close()
        except Exception:
            pass
