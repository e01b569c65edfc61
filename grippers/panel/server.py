"""``PanelServer``: the panel on uvicorn, in a thread of its own, for ``grippers panel`` and ``serve --http``.

The socket is bound here, before uvicorn starts, so port 0 gives a free port whose number is known at once
(the printed URL) and a port in use is an error at start, not a log line in a thread. Loopback unless told
otherwise; any other bind has a token (the caller's, else a new one, printed in the URL).

The WebSocket pings every ``PING_INTERVAL_S`` and drops a page that has not answered within
``PING_TIMEOUT_S``: that is how a page whose connection was lost (a cable pulled, a laptop asleep) is noticed,
and its motion stopped, within a second. The pings are answered by the browser itself, not by the page's
script, so a page in a background tab (whose timers the browser slows to once a minute) keeps control.
"""

from __future__ import annotations

import logging
import shutil
import socket
import tempfile
import threading
from pathlib import Path
from typing import Any

import uvicorn

from ..drivers.inet import family_of
from ..drivers.urls import parse_address, with_query
from ..errors import URLError
from ..gripper import Gripper
from .app import MAX_MESSAGE, Panel, make_app
from .security import Guard, is_loopback, new_token

log = logging.getLogger("grippers.panel")

DEFAULT_LISTEN = "127.0.0.1:0"
PING_INTERVAL_S = 0.25
PING_TIMEOUT_S = 0.5
START_TIMEOUT_S = 10.0


def parse_listen(text: str) -> tuple[str, int]:
    """``HOST:PORT`` (``[::1]:8000``, ``0.0.0.0:0``, ``:8000``: loopback) as (host, port); else URLError."""
    try:
        host, port = parse_address(text, listen=True)  # the one grammar: drivers/urls.py
    except URLError:
        raise URLError(
            f"--listen {text!r}: write HOST:PORT (127.0.0.1:8000; port 0 picks a free one)"
        ) from None
    return host or "127.0.0.1", port


class PanelServer:
    """Serve the panel for ``grippers`` (``{name: Gripper}``; the caller opens and closes them)."""

    def __init__(
        self,
        grippers: dict[str, Gripper],
        *,
        listen: str = DEFAULT_LISTEN,
        token: str | None = None,
        certfile: str | None = None,
        keyfile: str | None = None,
    ) -> None:
        self.host, port = parse_listen(listen)
        if token is not None and not token.strip():
            raise URLError("--token: an empty token")
        self.token = token if token is not None or is_loopback(self.host) else new_token()
        self.tls = certfile is not None
        self._sock = socket.socket(family_of(self.host), socket.SOCK_STREAM)
        try:
            self._sock.setsockopt(socket.SOL_SOCKET, socket.SO_REUSEADDR, 1)
            self._sock.bind((self.host, port))
        except OSError as exc:
            self._sock.close()
            raise URLError(f"--listen {listen}: {exc.strerror or exc}") from None
        self.port = int(self._sock.getsockname()[1])
        self._workdir = Path(tempfile.mkdtemp(prefix="grippers-panel-"))
        self.panel: Panel | None = None
        self._thread: threading.Thread | None = None
        try:
            self.panel = Panel(grippers, self._workdir)
            app = Guard(make_app(self.panel), token=self.token, port=self.port)
            config = uvicorn.Config(
                app,
                log_level="warning",
                lifespan="off",
                ws_ping_interval=PING_INTERVAL_S,
                ws_ping_timeout=PING_TIMEOUT_S,
                ws_max_size=MAX_MESSAGE,  # a larger frame closes the connection unread
                ssl_certfile=certfile,
                ssl_keyfile=keyfile,
                timeout_graceful_shutdown=1,
            )
            self._server = uvicorn.Server(config)
        except BaseException:
            self.close()
            raise

    @property
    def url(self) -> str:
        """Where a browser opens the panel (with the token, when there is one)."""
        host = self.host
        if host in ("0.0.0.0", "::"):
            host = socket.gethostname()
        elif ":" in host:
            host = f"[{host}]"
        scheme = "https" if self.tls else "http"
        return f"{scheme}://{host}:{self.port}/" + (f"?token={self.token}" if self.token else "")

    def start(self) -> PanelServer:
        self._sock.listen(128)
        self._thread = threading.Thread(
            target=self._server.run, kwargs={"sockets": [self._sock]}, name="grippers-panel", daemon=True
        )
        self._thread.start()
        waited = threading.Event()
        for _ in range(int(START_TIMEOUT_S / 0.01)):
            if self._server.started or not self._thread.is_alive():
                break
            waited.wait(0.01)
        if not self._server.started:
            self.close()
            raise URLError(f"the panel did not start on {self.host}:{self.port} (see the log)")
        log.info("panel at %s", with_query(self.url, {}))  # without the token
        return self

    def close(self) -> None:
        """Stop serving (pages are disconnected, their motions stopped), end recordings, remove the files."""
        if self._thread is not None:
            self._server.should_exit = True
            self._thread.join(timeout=5)
            self._thread = None
        if self.panel is not None:
            self.panel.close()
            self.panel = None
        self._sock.close()
        shutil.rmtree(self._workdir, ignore_errors=True)

    def __enter__(self) -> PanelServer:
        return self.start()

    def __exit__(self, *exc: Any) -> None:
        self.close()
