"""The panel's web application (Starlette): the page, its assets, the live WebSocket, recordings to download.

What crosses, and how (docs/panel.md):

- ``GET /``: the page; ``GET /static/…``: its script and style, shipped in the wheel (no CDN, no build step).
- ``GET /api/grippers``: every gripper's snapshot (read only). ``GET /api/grippers/NAME/recording.csv`` (or
  ``.mcap``): the last finished recording. No GET acts on a gripper.
- ``/ws``: the WebSocket each page opens. The server sends ``hello`` (the page's id, the server's choice),
  then ``update`` with the snapshots that changed (grippers/panel/pump.py), ``reply`` to each
  command, ``done`` when a motion the page started ends. The page sends commands: ``{"id": N, "name": GRIPPER,
  "command": "move", "args": {"width_mm": 40, "speed_mm_s": 50}}``. Commands travel nowhere else.

The security checks (token, Origin, Host) wrap all of it: grippers/panel/security.py.
"""

from __future__ import annotations

import asyncio
import itertools
import json
import logging
import secrets
from concurrent.futures import ThreadPoolExecutor
from pathlib import Path
from typing import Any

from starlette.applications import Starlette
from starlette.requests import Request
from starlette.responses import FileResponse, JSONResponse, PlainTextResponse, Response
from starlette.routing import Mount, Route, WebSocketRoute
from starlette.staticfiles import StaticFiles
from starlette.websockets import WebSocket, WebSocketDisconnect

from ..gripper import Gripper
from .control import Page
from .pump import PageLink, pump
from .session import GripperSession

log = logging.getLogger("grippers.panel")

STATIC = Path(__file__).resolve().parent / "static"
MAX_MESSAGE = 64 * 1024  # a command document larger than this is refused unread
MEDIA = {"csv": "text/csv", "mcap": "application/octet-stream"}


class Panel:
    """The grippers' sessions and the connected pages."""

    def __init__(self, grippers: dict[str, Gripper], workdir: Path) -> None:
        self.pages: dict[str, PageLink] = {}
        self._count = itertools.count(1)
        # Commands block on the device: their own pool, so a stop never waits behind the event loop's tasks.
        self.pool = ThreadPoolExecutor(max_workers=16, thread_name_prefix="grippers-panel")
        self.sessions: dict[str, GripperSession] = {}
        try:
            for name, g in grippers.items():
                self.sessions[name] = GripperSession(name, g, tell=self._tell, workdir=workdir)
        except BaseException:
            self.close()
            raise

    def _tell(self, page_id: str, message: dict[str, Any]) -> None:
        link = self.pages.get(page_id)
        if link is not None:
            link.post(message)

    def new_page(self, client: str) -> Page:
        return Page(id=secrets.token_hex(8), label=f"page {next(self._count)} at {client}")

    def close(self) -> None:
        for s in self.sessions.values():
            s.close()
        self.pool.shutdown(wait=False, cancel_futures=True)

    # -- HTTP ----------------------------------------------------------------------------------------------

    async def index(self, request: Request) -> Response:
        return FileResponse(STATIC / "index.html", headers={"cache-control": "no-store"})

    async def listing(self, request: Request) -> Response:
        return JSONResponse({"grippers": [s.snapshot() for s in self.sessions.values()]})

    async def download(self, request: Request) -> Response:
        session = self.sessions.get(request.path_params["name"])
        fmt = request.path_params["fmt"]
        path = session.download(fmt) if session is not None and fmt in MEDIA else None
        if path is None:
            return PlainTextResponse("no finished recording here\n", status_code=404)
        return FileResponse(path, media_type=MEDIA[fmt], filename=path.name)

    # -- the WebSocket -------------------------------------------------------------------------------------

    async def websocket(self, ws: WebSocket) -> None:
        await ws.accept()
        client = ws.client.host if ws.client is not None else "?"
        page = self.new_page(client)
        link = PageLink(page, asyncio.get_running_loop())
        self.pages[page.id] = link
        log.info("%s connected", page.label)
        sender = asyncio.create_task(pump(ws, link, self.sessions))
        tasks: set[asyncio.Task[None]] = set()
        try:
            await ws.send_json(
                {"type": "hello", "page": page.id, "label": page.label, "names": list(self.sessions)}
            )
            while True:
                text = await ws.receive_text()
                task = asyncio.create_task(self._command(link, text))
                tasks.add(task)
                task.add_done_callback(tasks.discard)
        except WebSocketDisconnect:
            pass
        finally:
            del self.pages[page.id]
            sender.cancel()
            log.info("%s left", page.label)
            # Its last commands first: a motion sent just before the page closed must not start after the
            # deadman looked, under a page that is gone.
            await asyncio.gather(*tasks, return_exceptions=True)
            loop = asyncio.get_running_loop()
            await asyncio.gather(
                *(loop.run_in_executor(self.pool, s.page_left, page) for s in self.sessions.values())
            )

    async def _command(self, link: PageLink, text: str) -> None:
        request_id: Any = None
        try:
            if len(text) > MAX_MESSAGE:
                raise ValueError(f"a command of {len(text)} characters (at most {MAX_MESSAGE})")
            message = json.loads(text)
            if not isinstance(message, dict):
                raise ValueError("a command is a JSON object")
            request_id = message.get("id")
            name, command, args = message.get("name"), message.get("command"), message.get("args", {})
            session = self.sessions.get(name) if isinstance(name, str) else None
            if session is None:
                raise ValueError(f"no gripper named {name!r} here")
            if not isinstance(command, str) or not isinstance(args, dict):
                raise ValueError("a command names its command (text) and its args (an object)")
        except ValueError as exc:  # json.JSONDecodeError too
            refused = {"ok": False, "error": "ProtocolError", "message": str(exc)}
            link.post({"type": "reply", "id": request_id, **refused})
            return
        loop = asyncio.get_running_loop()
        reply = await loop.run_in_executor(self.pool, session.run, link.page, command, args)
        link.post({"type": "reply", "id": request_id, "name": name, "command": command, **reply})

    def routes(self) -> list[Any]:
        return [
            Route("/", self.index),
            Route("/api/grippers", self.listing),
            Route("/api/grippers/{name}/recording.{fmt}", self.download),
            WebSocketRoute("/ws", self.websocket),
            Mount("/static", StaticFiles(directory=STATIC), name="static"),
        ]


def make_app(panel: Panel) -> Starlette:
    return Starlette(routes=panel.routes())
