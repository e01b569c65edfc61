"""The state pump: what the server sends one page, from one task, so writes never interleave.

Snapshots come from the sessions' streams (each gripper's ``Gripper.stream`` at 25 Hz, on its own thread),
and are sent ``STATE_HZ`` times a second at most, only those that changed since the page last got them; the
identity and limits only when they change (``info_seq``). Replies and motion outcomes for this page come
through its :class:`PageLink` from any thread and go out at once, between ticks.
"""

from __future__ import annotations

import asyncio
import json
import time
from typing import Any

from starlette.websockets import WebSocket, WebSocketDisconnect

from .control import Page
from .session import GripperSession

STATE_HZ = 30.0  # snapshots to each page at most this often (the issue asks 20 Hz or more)


class PageLink:
    """A connected page's outbox: messages from any thread, sent by the page's own task."""

    def __init__(self, page: Page, loop: asyncio.AbstractEventLoop) -> None:
        self.page = page
        self.loop = loop
        self.queue: asyncio.Queue[dict[str, Any]] = asyncio.Queue()

    def post(self, message: dict[str, Any]) -> None:
        try:
            self.loop.call_soon_threadsafe(self.queue.put_nowait, message)
        except RuntimeError:  # the loop has closed: the page is gone
            pass


async def pump(ws: WebSocket, link: PageLink, sessions: dict[str, GripperSession]) -> None:
    """The page's one writer: queued messages at once, changed snapshots every tick."""
    seen: dict[str, int] = {}
    seen_info: dict[str, int] = {}
    period = 1.0 / STATE_HZ
    next_tick = time.monotonic()
    try:
        while True:
            try:
                message = await asyncio.wait_for(link.queue.get(), max(0.0, next_tick - time.monotonic()))
                await ws.send_text(json.dumps(message))
                continue
            except TimeoutError:
                pass
            next_tick = max(next_tick + period, time.monotonic())
            changed = [
                s.snapshot(identity=seen_info.get(n) != s.info_seq)
                for n, s in sessions.items()
                if seen.get(n) != s.seq
            ]
            for snap in changed:
                seen[snap["name"]], seen_info[snap["name"]] = snap["seq"], snap["info_seq"]
            if changed:
                await ws.send_text(json.dumps({"type": "update", "grippers": changed}))
    except (WebSocketDisconnect, RuntimeError, OSError):
        pass  # the page went; the receiving side cleans up
