"""Issue 16 §6 and issue 12 §4: probe collapses identical failures, lists a garbage sender as one, takes
--profile, and shows the backend's warnings; plugin schemes are accepted (test_plugin_example.py)."""

from __future__ import annotations

import os
import socket
import threading
from collections.abc import Iterator

import pytest

from grippers.cli.probe import collapse


def test_identical_failures_are_one_line(cli) -> None:
    # No such SocketCAN interface (or no SocketCAN at all): sixteen STEPFOC nodes fail the same way.
    r = cli("probe", "can://socketcan/grippers-none0", "--timeout", "0.3")
    assert r.returncode == 1
    lines = [line for line in r.stdout.splitlines() if line.startswith("no answer")]
    assert len(lines) == 1, r.stdout  # the STEPFOC nodes and the WSG ids fail alike
    assert "and 16 more" in lines[0]
    assert len(cli("probe", "can://socketcan/grippers-none0", "-t", "0.3", "--json").json()["silent"]) == 17


def test_collapse_keeps_distinct_causes_apart() -> None:
    misses = [
        {"url": "a+tcp://h:1", "reason": "ConnectionLost: tcp://h:1: cannot connect: refused"},
        {"url": "a+tcp://h:2", "reason": "ConnectionLost: tcp://h:2: cannot connect: refused"},
        {"url": "a+tcp://h:3", "reason": "GripperTimeout: tcp://h:3: GET_SYSTEM_INFO (50h): no reply"},
    ]
    groups = collapse(misses)
    assert [urls for urls, _ in groups] == [["a+tcp://h:1", "a+tcp://h:2"], ["a+tcp://h:3"]]


@pytest.fixture
def garbage_server() -> Iterator[int]:
    """A TCP peer that answers every request with random bytes (a device on the wrong protocol)."""
    server = socket.create_server(("127.0.0.1", 0))
    stop = threading.Event()
    peers: list[socket.socket] = []

    def pump(conn: socket.socket) -> None:
        try:
            while not stop.is_set() and conn.recv(256):
                conn.sendall(os.urandom(40))
        except OSError:
            pass

    def accept() -> None:
        while not stop.is_set():
            try:
                conn, _ = server.accept()
            except OSError:
                return
            peers.append(conn)
            threading.Thread(target=pump, args=(conn,), daemon=True).start()

    thread = threading.Thread(target=accept, daemon=True)
    thread.start()
    yield server.getsockname()[1]
    stop.set()
    server.close()
    for peer in peers:
        peer.close()
    thread.join(2)


def test_a_device_sending_garbage_is_listed_as_such(cli, garbage_server: int) -> None:
    r = cli("probe", f"tcp://127.0.0.1:{garbage_server}", "--timeout", "0.5", "--json")
    doc = r.json()
    assert r.returncode == 1 and not doc["silent"], doc
    (other,) = doc["others"]
    assert "sends bytes that are not a wsg answer" in other["reason"]


def test_probe_profile_names_the_msg_model(cli, sim_process) -> None:
    sim = sim_process("msg", "--listen", "pty", "--profile", "msg-150")
    doc = cli("probe", sim.url, "--profile", "msg-200", "--timeout", "1", "--json").json()
    (device,) = doc["grippers"]
    assert device["model"] == "MSG 200" and device["profile"] == "msg-200"
    assert device["limits"]["max_width_mm"] == pytest.approx(155.0)


def test_probe_profile_unknown_is_a_usage_error(cli) -> None:
    r = cli("probe", "sim://wsg50", "--profile", "wsg5")
    assert r.returncode == 2 and "wsg5" in r.one_error_line()
