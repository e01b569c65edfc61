"""Who may reach the panel: the token, the Origin of commands, the Host of a tokenless panel.

One ASGI middleware in front of everything the panel serves (the page, its assets, the WebSocket, downloads):

- **The token** (when the panel has one; always off loopback): every request carries it, in the ``token``
  query parameter (the printed URL, as Jupyter does), an ``Authorization: Bearer`` header, or the cookie the
  panel sets on the first request that brought it in the URL (so the page's assets and its WebSocket carry it
  without it in every address). Missing: 401; wrong: 403; a WebSocket handshake is refused (403) either way.
- **The Origin** of every request that can act (anything but GET and HEAD) and of the WebSocket handshake,
  when a browser sends one, names this panel's own host and port: a page of another site cannot drive the
  grippers through the user's browser (cross-site request forgery, cross-site WebSocket hijacking).
- **The Host** of a panel without a token is a loopback name or address: a site that rebinds its DNS name to
  127.0.0.1 reaches the port, but its requests name its own host, and are refused (DNS rebinding).

Responses also forbid framing (clickjacking: a framed panel's buttons under someone else's page) and keep the
page's scripts to its own assets (Content-Security-Policy).
"""

from __future__ import annotations

import hmac
import ipaddress
import secrets
from collections.abc import Awaitable, Callable, MutableMapping
from http.cookies import SimpleCookie
from typing import Any

from grippers.drivers.urls import same_origin, web_fields, web_host

Scope = MutableMapping[str, Any]
Message = MutableMapping[str, Any]
Receive = Callable[[], Awaitable[Message]]
Send = Callable[[Message], Awaitable[None]]
ASGIApp = Callable[[Scope, Receive, Send], Awaitable[None]]

SAFE_METHODS = frozenset({"GET", "HEAD"})
HEADERS = [
    (b"x-frame-options", b"DENY"),
    (b"x-content-type-options", b"nosniff"),
    (b"referrer-policy", b"no-referrer"),  # the token in the URL is not sent on to another site
    (
        b"content-security-policy",
        b"default-src 'self'; connect-src 'self'; img-src 'self' data:; frame-ancestors 'none'",
    ),
]


def new_token() -> str:
    """A token for a panel bound off loopback without one: 192 random bits, URL-safe."""
    return secrets.token_urlsafe(24)


def is_loopback(host: str) -> bool:
    """``127.0.0.1``, ``::1``, ``localhost``: a name or address only this machine reaches."""
    host = web_host(host)
    if host.lower() == "localhost" or host.lower().endswith(".localhost"):
        return True
    try:
        return ipaddress.ip_address(host).is_loopback
    except ValueError:
        return False


def cookie_name(port: int) -> str:
    """Cookies are not kept apart by port: two panels on one host need two names."""
    return f"grippers_panel_{port}"


def _headers(scope: Scope) -> dict[str, str]:
    return {k.decode("latin-1").lower(): v.decode("latin-1") for k, v in scope.get("headers", [])}


class Guard:
    """The middleware: ``Guard(app, token=..., port=...)``; ``token=None`` only on a loopback bind."""

    def __init__(self, app: ASGIApp, *, token: str | None, port: int) -> None:
        self.app = app
        self.token = token
        self.cookie = cookie_name(port)

    async def __call__(self, scope: Scope, receive: Receive, send: Send) -> None:
        if scope["type"] not in ("http", "websocket"):
            await self.app(scope, receive, send)
            return
        headers = _headers(scope)
        status, why, from_url = self._check(scope, headers)
        if status:
            await _refuse(scope, receive, send, status, why)
            return

        async def send_with_headers(message: Message) -> None:
            if message["type"] == "http.response.start":
                extra = list(HEADERS)
                if from_url and self.token:
                    value = f"{self.cookie}={self.token}; Path=/; HttpOnly; SameSite=Strict"
                    if scope.get("scheme") == "https":
                        value += "; Secure"
                    extra.append((b"set-cookie", value.encode("latin-1")))
                message["headers"] = [*message.get("headers", []), *extra]
            await send(message)

        await self.app(scope, receive, send_with_headers)

    def _check(self, scope: Scope, headers: dict[str, str]) -> tuple[int, str, bool]:
        """``(status, reason, token came in the URL)``; status 0 lets the request through."""
        host = headers.get("host", "")
        if self.token is None and not is_loopback(web_host(host)):
            return 403, "this panel answers loopback names only (start it with --token for others)", False
        acts = scope["type"] == "websocket" or scope.get("method", "GET") not in SAFE_METHODS
        origin = headers.get("origin")
        if acts and origin is not None and not same_origin(origin, host):
            return 403, "cross-origin request refused", False
        if self.token is None:
            return 0, "", False
        given, from_url = self._given(scope, headers)
        if given is None:
            return 401, "token required (open the URL the panel printed)", False
        if not hmac.compare_digest(given.encode("utf-8", "replace"), self.token.encode("utf-8")):
            return 403, "wrong token", False
        return 0, "", from_url

    def _given(self, scope: Scope, headers: dict[str, str]) -> tuple[str | None, bool]:
        query = web_fields(scope.get("query_string", b"").decode("latin-1"), "panel request")
        if query.get("token"):
            return query["token"], True
        auth = headers.get("authorization", "")
        if auth.lower().startswith("bearer "):
            return auth[7:].strip(), False
        jar: SimpleCookie = SimpleCookie()
        try:
            jar.load(headers.get("cookie", ""))
        except Exception:  # a malformed Cookie header is no token
            return None, False
        morsel = jar.get(self.cookie)
        return (morsel.value, False) if morsel is not None else (None, False)


async def _refuse(scope: Scope, receive: Receive, send: Send, status: int, why: str) -> None:
    if scope["type"] == "websocket":
        await receive()  # websocket.connect
        await send({"type": "websocket.close", "code": 1008, "reason": why})  # the server answers 403
        return
    body = f"{status} {why}\n".encode()
    await send(
        {
            "type": "http.response.start",
            "status": status,
            "headers": [
                (b"content-type", b"text/plain; charset=utf-8"),
                (b"content-length", str(len(body)).encode()),
                *HEADERS,
            ],
        }
    )
    await send({"type": "http.response.body", "body": body})
