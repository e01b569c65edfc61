"""The panel's tests: a real uvicorn server on loopback (grippers/panel/server.py) over simulators.

The tests in this folder without the ``browser`` marker speak HTTP and WebSocket themselves (httpx and the
``websockets`` client); the ``browser`` ones drive Debian's chromium with Playwright and run through
scripts/run-browser-tests.sh, which sets ``GRIPPERS_BROWSER_TESTS=1`` (without it they skip, naming the
script, as the ROS 2 tests do).
"""

from __future__ import annotations

import json
import threading
import time
from collections.abc import Callable, Iterator
from typing import Any

import pytest

pytest.importorskip("starlette", reason="the panel extra: pip install '.[panel]'")
pytest.importorskip("uvicorn", reason="the panel extra: pip install '.[panel]'")

import grippers
from grippers.panel.server import PanelServer

from .browser import CHROMIUM, Tab


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
    """A page as the server sees it, without a browser: the WebSocket, commands and what comes back.

    A thread reads everything the server sends as it comes, as a browser does: a client that stopped reading
    would stop answering the server's pings too, and be dropped as a page whose connection was lost."""

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
        self._changed = threading.Condition()
        self.snapshots: dict[str, dict[str, Any]] = {}
        self.replies: dict[Any, dict[str, Any]] = {}
        self.done: list[dict[str, Any]] = []
        self._reader = threading.Thread(target=self._read, daemon=True)
        self._reader.start()

    def _read(self) -> None:
        try:
            for text in self.ws:
                message = json.loads(text)
                with self._changed:
                    if message["type"] == "update":
                        for snap in message["grippers"]:
                            name = snap["name"]
                            self.snapshots[name] = {**self.snapshots.get(name, {}), **snap}
                    elif message["type"] == "done":
                        self.done.append(message)
                    elif message["type"] == "reply":
                        self.replies[message.get("id")] = message
                    self._changed.notify_all()
        except Exception:
            pass

    def command(self, name: str, command: str, **args: Any) -> dict[str, Any]:
        """Send one command; its reply."""
        self._next += 1
        self.ws.send(json.dumps({"id": self._next, "name": name, "command": command, "args": args}))
        return self.reply(self._next)

    def send_raw(self, text: str) -> None:
        self.ws.send(text)

    def reply(self, request_id: Any) -> dict[str, Any]:
        with self._changed:
            if not self._changed.wait_for(lambda: request_id in self.replies, timeout=10):
                raise AssertionError(f"no reply to {request_id}")
            return dict(self.replies.pop(request_id))

    def pump(self, seconds: float = 0.1) -> None:
        """Let ``seconds`` of updates come in."""
        time.sleep(seconds)

    def close(self) -> None:
        self._connection.__exit__(None, None, None)
        self._reader.join(5)


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


# -- the browser (tests marked ``browser``: Playwright is imported by these fixtures only) ----------------


@pytest.fixture(scope="module")
def chromium() -> Iterator[Any]:
    from playwright.sync_api import sync_playwright  # the browser tests' own dependency

    with sync_playwright() as p:
        browser = p.chromium.launch(executable_path=CHROMIUM, args=["--no-sandbox"])
        try:
            yield browser
        finally:
            browser.close()


@pytest.fixture
def tab(chromium: Any) -> Iterator[Callable[..., Tab]]:
    """``tab(url)``: a new browser context (its own cookies) on the panel, loaded and connected."""
    contexts: list[Any] = []

    def open_(url: str, *, wait_connected: bool = True) -> Tab:
        context = chromium.new_context(viewport={"width": 1280, "height": 900}, accept_downloads=True)
        context.set_default_timeout(10_000)
        contexts.append(context)
        t = Tab(context.new_page())
        t.response = t.page.goto(url)
        if wait_connected:
            t.page.get_by_text("connected as page").wait_for()
        return t

    yield open_
    for c in contexts:
        c.close()
