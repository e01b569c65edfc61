"""Faults: hostile payloads, a server killed, a gripper that disconnects, leaks after close, where we bind."""

from __future__ import annotations

import json
import os
import signal
import threading
import time

import pytest
import zenoh

import grippers
from grippers.remote import protocol

from .conftest import ServeProcess, sim

pytestmark = pytest.mark.timeout(60)


def _raw_session(endpoint: str) -> zenoh.Session:
    config = zenoh.Config()
    config.insert_json5("mode", '"client"')
    config.insert_json5("connect/endpoints", json.dumps([endpoint]))
    config.insert_json5("scouting/multicast/enabled", "false")
    return zenoh.open(config)


BAD_PAYLOADS = [
    b"\xff\xfe not utf-8",
    b"not json",
    b"[1, 2, 3]",
    b'{"args": {"width": "wide"}}',
    b'{"args": {"width": NaN}}',
    b'{"args": {"width": true}}',
    b'{"args": {"width": 1e400}}',
    b'{"args": {"width": 0.05, "colour": "red"}}',
    b'{"args": {}}',
    b'{"v": 99, "client": "x", "args": {"width": 0.05}}',
    b'{"client": ["x"], "args": {"width": 0.05}}',
    b'{"client": "x", "args": {"width": 0.05}, "extra": 1}',
    b"[" * 100_000,
    b'{"client": "x", "args": {"width": 0.05}}' + b" " * (protocol.MAX_PAYLOAD + 1),
]


def test_malformed_payloads_get_an_error_and_reach_nothing(serve) -> None:
    server: ServeProcess = serve(f"g={sim('wsg50')}")
    with grippers.open(server.urls["g"]) as g:
        g.home()
        g.move(0.07)
        before = g.state()
        session = _raw_session(server.endpoint)
        try:
            for payload in BAD_PAYLOADS:
                replies = list(session.get("grippers/g/cmd/move", payload=payload, timeout=2))
                assert len(replies) == 1, payload[:40]
                assert replies[0].err is not None, payload[:40]
                doc = json.loads(replies[0].err.payload.to_bytes())
                assert doc["error"] == "ProtocolError" and doc["command"] == "move", doc
            for key in ("grippers/g/cmd/nonsense", "grippers/g/cmd/control"):
                replies = list(session.get(key, payload=b'{"args": {"action": "steal"}}', timeout=2))
                assert all(r.err is not None for r in replies)
        finally:
            session.close()
        after = g.state()
        assert after.width == pytest.approx(before.width, abs=1e-6)
        assert not after.moving
        assert g.move(0.05).width == pytest.approx(0.05, abs=0.002)  # the server still serves


def test_server_killed_is_connection_lost_never_a_hang(serve) -> None:
    server: ServeProcess = serve(f"g={sim('wsg50', scale=1)}")
    g = grippers.open(server.urls["g"], timeout=1.0)
    try:
        g.home()
        handle = g.move(g.limits.min_width + 0.001, g.limits.min_speed, wait=False)
        time.sleep(0.1)
        server.proc.send_signal(signal.SIGKILL)
        start = time.monotonic()
        with pytest.raises(grippers.ConnectionLost):
            handle.wait(5)
        with pytest.raises(grippers.ConnectionLost):
            g.state()
        with pytest.raises(grippers.ConnectionLost):
            g.move(0.05)
        assert time.monotonic() - start < 3.0
    finally:
        g.close()


def test_gripper_disconnect_withdraws_it(serve, sim_process) -> None:
    device = sim_process("wsg", "--listen", "tcp://127.0.0.1:0", "--time-scale", "50")
    server: ServeProcess = serve(f"dev={device.url}", f"other={sim('msg-150')}", "--rate", "100")
    with grippers.open(server.urls["dev"]) as g, grippers.open(server.urls["other"]) as other:
        stream = g.stream(rate_hz=100)
        stream.get(5)
        device.close()  # the gripper's TCP connection drops
        with pytest.raises(grippers.ConnectionLost):
            for _ in range(500):
                stream.get(5)
        with pytest.raises(grippers.ConnectionLost):
            g.state()
        assert other.state().width > 0  # the server and its other gripper go on
    served = grippers.remote.served_urls(f"zenoh://?connect={server.endpoint}", timeout=1)
    assert [u.split("?")[0] for u in served] == ["zenoh://other"]


def _socket_inodes(pid: int | str) -> set[str]:
    out = set()
    for fd in os.listdir(f"/proc/{pid}/fd"):
        try:
            target = os.readlink(f"/proc/{pid}/fd/{fd}")
        except OSError:
            continue
        if target.startswith("socket:["):
            out.add(target[8:-1])
    return out


def _listening(pid: int) -> list[str]:
    """Local addresses of the TCP sockets ``pid`` listens on (state 0A), from /proc/net/tcp and tcp6."""
    inodes = _socket_inodes(pid)
    found = []
    for table in ("/proc/net/tcp", "/proc/net/tcp6"):
        with open(table) as f:
            for line in f.readlines()[1:]:
                cols = line.split()
                if cols[3] == "0A" and cols[9] in inodes:
                    found.append(cols[1])
    return found


def test_eight_grippers_no_leaks_loopback_only(serve) -> None:
    targets = [f"g{i}={sim('wsg50' if i % 2 else 'msg-150')}" for i in range(8)]
    server: ServeProcess = serve(*targets, "--rate", "100")
    listening = _listening(server.proc.pid)
    assert listening, "the server listens somewhere"
    # 0100007F is 127.0.0.1 in /proc/net/tcp's byte order; nothing on 0.0.0.0 or [::].
    assert all(addr.split(":")[0] == "0100007F" for addr in listening), listening

    threads_before = {t.ident for t in threading.enumerate()}
    sockets_before = _socket_inodes("self")
    names = grippers.remote.served_names([server.endpoint], timeout=1)
    assert names == sorted(f"g{i}" for i in range(8))
    opened = [grippers.open(server.urls[n]) for n in names]
    try:
        streams = [g.stream(rate_hz=100) for g in opened]
        for s in streams:
            s.get(5)
        for g in opened:
            assert g.state().width >= 0
    finally:
        for g in opened:
            g.close()
    deadline = time.monotonic() + 5
    while time.monotonic() < deadline:
        leaked_threads = [t for t in threading.enumerate() if t.ident not in threads_before]
        leaked_sockets = _socket_inodes("self") - sockets_before
        if not leaked_threads and not leaked_sockets:
            break
        time.sleep(0.05)
    assert not leaked_threads
    assert not leaked_sockets


def test_payloads_follow_the_published_schemas(serve) -> None:
    from grippers.remote.schemas import SCHEMAS

    server: ServeProcess = serve(f"g={sim('wsg50')}")
    session = _raw_session(server.endpoint)
    try:
        (info,) = session.get("grippers/g/info", timeout=2)
        SCHEMAS["grippers.remote.info/1"].model_validate_json(info.ok.payload.to_bytes())
        (state,) = session.get("grippers/g/state", timeout=2)
        SCHEMAS["grippers.remote.state/1"].model_validate_json(state.ok.payload.to_bytes())
        request = protocol.encode_request("raw", "test", {"width": 0.05})
        SCHEMAS["grippers.remote.request/1"].model_validate_json(request)
        token = session.liveliness().declare_token("grippers/g/client/raw")  # noqa: F841  # kept: declared  # a free lease goes to a token's owner
        time.sleep(0.2)
        home = protocol.encode_request("raw", "test", {})
        every = zenoh.ConsolidationMode.NONE  # the pending and the final reply, both
        replies = list(session.get("grippers/g/cmd/home", payload=home, consolidation=every, timeout=10))
        docs = [r.ok.payload.to_bytes() for r in replies]
        assert [json.loads(d)["status"] for d in docs] == ["pending", "done"]
        for d in docs:
            SCHEMAS["grippers.remote.reply/1"].model_validate_json(d)
        secret = json.loads(docs[0])["lease"]  # the request that took the lease is answered its secret
        with_secret = protocol.encode_request("raw", "test", {"width": 0.05}, secret)
        SCHEMAS["grippers.remote.request/1"].model_validate_json(with_secret)
        (err,) = session.get("grippers/g/cmd/move", payload=b"{}", timeout=2)
        SCHEMAS["grippers.remote.error/1"].model_validate_json(err.err.payload.to_bytes())
    finally:
        session.close()
