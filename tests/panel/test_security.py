"""Issue 42 §3: the token on every request off loopback, the Origin of commands, the Host of a tokenless
panel, and no command over GET. Against a real uvicorn server on loopback (HTTP with httpx, WebSocket with
the websockets client)."""

from __future__ import annotations

from typing import Any

import httpx
import pytest
from websockets.exceptions import InvalidStatus
from websockets.sync.client import connect

from grippers.errors import URLError
from grippers.panel.security import is_loopback
from grippers.panel.server import PanelServer, parse_listen


def _get(server: PanelServer, path: str, **kwargs: Any) -> httpx.Response:
    return httpx.get(f"http://127.0.0.1:{server.port}{path}", timeout=5, **kwargs)


def test_loopback_by_default_without_a_token(opened, serve) -> None:
    server = serve({"g": opened("sim://wsg50")})
    assert server.host == "127.0.0.1" and server.token is None
    assert server.url == f"http://127.0.0.1:{server.port}/"
    assert _get(server, "/").status_code == 200
    assert _get(server, "/static/panel.js").status_code == 200


def test_a_tokenless_panel_refuses_other_host_names(opened, serve) -> None:
    """DNS rebinding: a site whose name now points at 127.0.0.1 sends its own name as Host."""
    server = serve({"g": opened("sim://wsg50")})
    refused = _get(server, "/", headers={"Host": f"evil.example:{server.port}"})
    assert refused.status_code == 403
    assert _get(server, "/", headers={"Host": f"localhost:{server.port}"}).status_code == 200


def test_any_other_bind_gets_a_token_checked_on_every_request(opened, serve) -> None:
    server = serve({"g": opened("sim://wsg50")}, listen="0.0.0.0:0")
    assert server.token and len(server.token) >= 32
    assert server.url.endswith(f":{server.port}/?token={server.token}")
    for path in ("/", "/static/panel.js", "/static/panel.css", "/api/grippers"):
        assert _get(server, path).status_code == 401, path
        assert _get(server, path, params={"token": "wrong"}).status_code == 403, path
    first = _get(server, "/", params={"token": server.token})
    assert first.status_code == 200
    cookie = first.headers["set-cookie"]
    assert f"grippers_panel_{server.port}={server.token}" in cookie and "HttpOnly" in cookie
    assert "SameSite=Strict" in cookie
    jar = {f"grippers_panel_{server.port}": server.token}
    assert _get(server, "/static/panel.js", cookies=jar).status_code == 200  # the page's assets
    bearer = {"Authorization": f"Bearer {server.token}"}
    assert _get(server, "/api/grippers", headers=bearer).status_code == 200


def test_the_websocket_needs_the_token(opened, serve, page) -> None:
    server = serve({"g": opened("sim://wsg50")}, listen="0.0.0.0:0")
    url = f"ws://127.0.0.1:{server.port}/ws"
    for headers in ({}, {"Authorization": "Bearer wrong"}):
        with pytest.raises(InvalidStatus) as refused:
            connect(url, additional_headers=headers, open_timeout=5)
        assert refused.value.response.status_code == 403
    client = page(server)  # with the token: a page
    assert client.command("g", "stop")["ok"]


def test_a_given_token_is_required_on_loopback_too(opened, serve) -> None:
    server = serve({"g": opened("sim://wsg50")}, token="s3cret-token")
    assert server.url.endswith("?token=s3cret-token")
    assert _get(server, "/").status_code == 401
    assert _get(server, "/", params={"token": "s3cret-token"}).status_code == 200


def test_the_origin_of_commands_is_checked(opened, serve, page) -> None:
    server = serve({"g": opened("sim://wsg50")})
    url = f"ws://127.0.0.1:{server.port}/ws"
    with pytest.raises(InvalidStatus) as refused:
        connect(url, origin="http://evil.example", open_timeout=5)  # type: ignore[arg-type]
    assert refused.value.response.status_code == 403
    post = httpx.post(
        f"http://127.0.0.1:{server.port}/api/grippers", headers={"Origin": "http://evil.example"}, timeout=5
    )
    assert post.status_code == 403
    same = page(server, origin=f"http://127.0.0.1:{server.port}")  # the panel's own page
    assert same.command("g", "stop")["ok"]


def test_no_get_acts_on_a_gripper(opened, serve) -> None:
    g = opened("sim://wsg50")
    server = serve({"g": g})
    for path in ("/api/grippers/g/move?width_mm=40", "/api/grippers/g/home", "/ws/g/home", "/api/g/stop"):
        assert _get(server, path).status_code in (404, 405), path
    assert not g.state().referenced  # nothing homed it


def test_responses_forbid_framing_and_foreign_scripts(opened, serve) -> None:
    server = serve({"g": opened("sim://wsg50")})
    headers = _get(server, "/").headers
    assert headers["x-frame-options"] == "DENY"
    assert "frame-ancestors 'none'" in headers["content-security-policy"]
    assert "default-src 'self'" in headers["content-security-policy"]


def test_listen_addresses() -> None:
    assert parse_listen("127.0.0.1:0") == ("127.0.0.1", 0)
    assert parse_listen("[::1]:8000") == ("::1", 8000)
    assert parse_listen(":8000") == ("127.0.0.1", 8000)
    for bad in ("localhost", "h:99999", "h:x", ""):
        with pytest.raises(URLError):
            parse_listen(bad)
    assert is_loopback("127.0.0.1") and is_loopback("::1") and is_loopback("localhost")
    assert not is_loopback("0.0.0.0") and not is_loopback("192.168.1.5") and not is_loopback("evil.example")


def test_a_port_in_use_is_a_clear_error(opened, serve) -> None:
    server = serve({"g": opened("sim://wsg50")})
    with pytest.raises(URLError, match=f"127.0.0.1:{server.port}"):
        PanelServer({"g": opened("sim://wsg50")}, listen=f"127.0.0.1:{server.port}")
