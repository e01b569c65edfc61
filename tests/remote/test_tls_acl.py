"""Issue 30 §2: Zenoh's own security, as docs/remote.md's "Security" recipe configures it.

Mutual TLS: a client without a certificate of the cell's authority cannot even connect. Access control:
every authenticated client reads state and info, only the controller's certificate identity sends
``cmd/**``: the observer's command is refused by Zenoh itself (it never reaches the server), while a command
with the controller's identity but without the lease secret is refused by the server (the application's
refusal)."""

from __future__ import annotations

import json
from pathlib import Path

import pytest
import zenoh

import grippers
from grippers import AccessDenied, ConnectionLost

from .conftest import ServeProcess, sim
from .tls import make_cell

pytestmark = pytest.mark.timeout(120)


@pytest.fixture
def cell(tmp_path: Path, serve) -> tuple[ServeProcess, dict[str, Path]]:
    files = make_cell(tmp_path)
    server = serve(f"g={sim('wsg50')}", "--zenoh-config", str(files["server"]), listen="tls/127.0.0.1:0")
    assert server.endpoint.startswith("tls/")
    return server, files


def _url(server: ServeProcess, config: Path) -> str:
    return f"{server.urls['g']}&zenoh_config={config}&timeout=1"


def _raw(server: ServeProcess, config: Path) -> zenoh.Session:
    c = zenoh.Config.from_file(str(config))
    c.insert_json5("mode", '"client"')
    c.insert_json5("connect/endpoints", json.dumps([server.endpoint]))
    c.insert_json5("scouting/multicast/enabled", "false")
    return zenoh.open(c)


def test_a_client_without_a_valid_certificate_cannot_connect(cell) -> None:
    server, files = cell
    for who in ("no-cert", "intruder"):  # no certificate; one of another authority
        with pytest.raises(ConnectionLost, match="cannot open a Zenoh session"):
            grippers.open(_url(server, files[who]))
        with pytest.raises(Exception):  # noqa: B017, PT011  # zenoh's own error type
            _raw(server, files[who])
    plain = server.urls["g"].replace("tls/", "tcp/")  # plain TCP to the TLS port
    with pytest.raises(ConnectionLost):
        grippers.open(plain + "&timeout=1")


def test_the_controller_commands_and_the_observer_only_observes(cell) -> None:
    server, files = cell
    with grippers.open(_url(server, files["controller"]) + "&label=cell") as controller:
        controller.home()
        assert controller.move(0.05).width == pytest.approx(0.05, abs=0.001)
        with grippers.open(_url(server, files["observer"])) as observer:
            assert observer.state().width == pytest.approx(0.05, abs=0.001)  # reads: allowed
            assert observer.info().model
            stream = observer.stream(rate_hz=20)
            assert stream.get(timeout=5).width == pytest.approx(0.05, abs=0.001)
            stream.close()
            controller.release_control()  # a free lease: only the network stands in the way now
            with pytest.raises(AccessDenied, match="Zenoh network refused"):
                observer.move(0.07)  # refused by Zenoh's access control, not by the server
            assert observer.connected and observer.state().width == pytest.approx(0.05, abs=0.001)
        assert controller.move(0.06).width == pytest.approx(0.06, abs=0.001)


def test_the_network_refusal_and_the_application_refusal_seen_raw(cell) -> None:
    """Raw sessions, no grippers code: the observer's query on cmd/move reaches no queryable at all; the
    controller identity's query without the lease secret reaches the server and is answered AccessDenied."""
    server, files = cell
    with grippers.open(_url(server, files["controller"])) as holder:
        holder.home()
        holder.move(0.04)
        request = {"v": 1, "client": holder.client_id, "label": "raw", "args": {"width": 0.085}}
        observer = _raw(server, files["observer"])
        try:
            (state,) = observer.get("grippers/g/state", timeout=3)
            assert state.ok is not None  # reads are allowed
            replies = list(observer.get("grippers/g/cmd/move", payload=json.dumps(request), timeout=3))
            assert all(r.ok is None for r in replies)  # nothing answered: Zenoh dropped it
        finally:
            observer.close()
        second = _raw(server, files["controller"])  # the controller's identity, another session
        try:
            replies = list(second.get("grippers/g/cmd/move", payload=json.dumps(request), timeout=3))
            assert len(replies) == 1 and replies[0].err is not None
            assert json.loads(replies[0].err.payload.to_bytes())["error"] == "AccessDenied"
        finally:
            second.close()
        assert holder.state().width == pytest.approx(0.04, abs=0.001)  # nothing moved
