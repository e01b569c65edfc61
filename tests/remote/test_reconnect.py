"""Issue 15 over ``zenoh://``: ``reconnect=true`` survives a server killed and restarted on the same port."""

from __future__ import annotations

import signal
import socket
import time

import pytest

import grippers
from grippers import ConnectionLost

from .conftest import ServeProcess, sim


def _free_port() -> int:
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return int(s.getsockname()[1])


def _until(predicate, bound: float) -> bool:  # type: ignore[no-untyped-def]
    deadline = time.monotonic() + bound
    while time.monotonic() < deadline:
        if predicate():
            return True
        time.sleep(0.02)
    return False


def test_a_restarted_server_is_taken_up_again() -> None:
    port = _free_port()
    listen = f"tcp/127.0.0.1:{port}"
    server = ServeProcess(f"left={sim('wsg50')}", listen=listen)
    events: list[bool] = []
    try:
        url = server.urls["left"] + "&reconnect=true&heartbeat_s=0.2&reconnect_backoff_max_s=0.5"
        with grippers.open(url) as g:
            g.on_connection(events.append)
            g.home()
            server.close(signal.SIGKILL)
            assert _until(lambda: not g.connected, 10.0), "the loss was not noticed"
            try:
                g.state()
                raise AssertionError("state() answered during the outage")
            except ConnectionLost:
                pass
            server = ServeProcess(f"left={sim('wsg50')}", listen=listen)
            back = _until(lambda: g.connected and len(events) >= 2, 20.0)  # listeners are told after the flag
            assert back, "the restarted server was not taken up"
            assert events[:2] == [False, True]
            assert not g.state().referenced  # a new simulator (a power-cycled gripper): not homed
            g.home()
            assert g.move(0.05).width == pytest.approx(0.05, abs=0.001)
    finally:
        server.close()
