"""Issue 42 §2: what pages send, checked by the simulators' own state (no browser: the WebSocket as a page
speaks it). Control (one page at a time, Take control, stop from anyone), the deadman (a controlling page
gone mid-motion stops the jaws within 1 s), refusals with the library's messages, the Record toggle."""

from __future__ import annotations

import base64
import csv
import io
import json
import os
import socket
import time
from typing import Any

import httpx

from .conftest import wait_for


def test_buttons_act_on_the_simulator(opened, serve, page) -> None:
    g = opened("sim://wsg50?time_scale=20")
    server = serve({"left": g})
    p = page(server)
    assert p.command("left", "home") == {
        "type": "reply",
        "id": 1,
        "name": "left",
        "command": "home",
        "ok": True,
        "started": True,
    }
    wait_for(lambda: g.state().referenced and not g.state().moving, "homed")
    assert p.command("left", "move", width_mm=40, speed_mm_s=100)["ok"]
    wait_for(lambda: abs(g.state().width - 0.040) < 5e-4 and not g.state().moving, "at 40 mm")
    assert p.command("left", "jog", delta_mm=-10, speed_mm_s=100)["ok"]
    wait_for(lambda: abs(g.state().width - 0.030) < 5e-4 and not g.state().moving, "jogged to 30 mm")
    assert p.command("left", "fast_stop")["ok"]
    assert g.state().fast_stopped
    assert p.command("left", "acknowledge")["ok"]
    assert not g.state().fast_stopped


def test_a_refused_command_says_the_librarys_message(opened, serve, page) -> None:
    g = opened("sim://wsg50?time_scale=20")
    p = page(serve({"left": g}))
    reply = p.command("left", "move", width_mm=400)
    assert reply["ok"] is False and reply["error"] == "LimitError"
    assert reply["message"] == "move: width 400 mm is outside 0..110 mm"
    p.command("left", "fast_stop")
    reply = p.command("left", "move", width_mm=40)
    assert reply["error"] == "FastStopActive"
    assert reply["message"].startswith("move: fast stop is active")
    for bad in ({"width_mm": "40"}, {"width_mm": True}, {"width_mm": 1e400}, {"colour": 1}):
        reply = p.command("left", "move", **bad)
        assert reply["ok"] is False and reply["error"] == "LimitError", bad
    assert p.command("left", "reboot")["ok"] is False
    p.send_raw("{not json")
    assert p.reply(None)["error"] == "ProtocolError"
    p.send_raw('{"id": 7, "name": "nobody", "command": "stop"}')
    assert "no gripper named 'nobody'" in p.reply(7)["message"]
    assert g.state().fast_stopped  # nothing above reached the device


def test_one_page_controls_others_observe_and_may_stop(opened, serve, page) -> None:
    g = opened("sim://wsg50?time_scale=20")
    server = serve({"left": g})
    first, second = page(server), page(server)
    assert first.command("left", "home")["ok"]  # acting takes control
    wait_for(lambda: g.state().referenced and not g.state().moving, "homed")
    refused = second.command("left", "move", width_mm=20)
    assert refused["error"] == "AccessDenied"
    assert first.label in refused["message"] and "Take control" in refused["message"]
    assert second.command("left", "stop")["ok"]  # anyone may stop
    assert second.command("left", "take_control")["ok"]
    assert second.command("left", "move", width_mm=20, speed_mm_s=200)["ok"]
    assert first.command("left", "move", width_mm=60)["error"] == "AccessDenied"
    wait_for(lambda: abs(g.state().width - 0.020) < 5e-4, "second page's move")
    first.pump(0.2)
    assert first.snapshots["left"]["controller"] == {"id": second.page, "label": second.label}


MARGIN = 0.5  # a state read and a stop on a busy machine, beyond the 1 s


def _silent_page(port: int, command: dict[str, object]) -> socket.socket:
    """A page that sends one command over a WebSocket it opened by hand, then goes silent: it answers no
    ping and never closes (a cable pulled, a laptop asleep)."""
    sock = socket.create_connection(("127.0.0.1", port), timeout=5)
    key = base64.b64encode(os.urandom(16)).decode()
    sock.sendall(
        f"GET /ws HTTP/1.1\r\nHost: 127.0.0.1:{port}\r\nUpgrade: websocket\r\nConnection: Upgrade\r\n"
        f"Sec-WebSocket-Key: {key}\r\nSec-WebSocket-Version: 13\r\n\r\n".encode()
    )
    head = b""
    while b"\r\n\r\n" not in head:
        head += sock.recv(1)
    assert head.startswith(b"HTTP/1.1 101"), head
    payload = json.dumps(command).encode()
    mask = os.urandom(4)
    assert len(payload) < 126
    frame = bytes([0x81, 0x80 | len(payload)]) + mask + bytes(b ^ mask[i % 4] for i, b in enumerate(payload))
    sock.sendall(frame)
    return sock


def test_a_controlling_page_gone_silent_mid_motion_stops_the_jaws(opened, serve, page) -> None:
    """No close, no FIN: the server's pings go unanswered and the page is dropped within their bound."""
    g = opened("sim://wsg50")
    g.home()
    server = serve({"left": g})
    observer = page(server)
    silent = _silent_page(
        server.port, {"id": 1, "name": "left", "command": "move", "args": {"width_mm": 0, "speed_mm_s": 5}}
    )
    try:
        wait_for(lambda: g.state().moving, "moving")
        silent_since = time.monotonic()
        wait_for(lambda: not g.state().moving, "stopped after the page went silent", timeout=5)
        assert time.monotonic() - silent_since < 1.0 + MARGIN
        assert g.state().width > 0.1  # stopped, not arrived
        wait_for(lambda: observer.snapshots["left"]["controller"] is None, "control freed")
    finally:
        silent.close()


def _closing_from(p: Any, g: Any, speed_mm_s: float) -> None:
    """``p`` homes ``g`` and sets it closing from 110 mm at ``speed_mm_s`` (real time)."""
    assert p.command("left", "home")["ok"]
    wait_for(lambda: g.state().referenced and not g.state().moving, "homed", timeout=30)
    assert p.command("left", "move", width_mm=0, speed_mm_s=speed_mm_s)["ok"]
    wait_for(lambda: g.state().moving, "moving")


def test_a_controlling_page_gone_mid_motion_stops_the_jaws(opened, serve, page) -> None:
    g = opened("sim://wsg50")  # real time: a 100 mm move at 5 mm/s lasts 20 s
    server = serve({"left": g})
    observer, p = page(server), page(server)
    _closing_from(p, g, 5)
    p.close()
    gone = time.monotonic()
    wait_for(lambda: not g.state().moving, "stopped after the page left", timeout=5)
    assert time.monotonic() - gone < 1.0 + MARGIN
    width = g.state().width
    assert width > 0.05  # stopped, not arrived
    time.sleep(0.3)
    assert abs(g.state().width - width) < 2e-4
    observer.pump(0.2)
    assert observer.snapshots["left"]["controller"] is None


def test_an_observer_leaving_stops_nothing(opened, serve, page) -> None:
    g = opened("sim://wsg50")
    server = serve({"left": g})
    p, observer = page(server), page(server)
    _closing_from(p, g, 20)
    observer.close()
    time.sleep(0.5)
    assert g.state().moving


def test_record_then_download_csv_and_mcap(opened, serve, page) -> None:
    g = opened("sim://wsg50?time_scale=20")
    server = serve({"left-1": g})
    p = page(server)
    assert p.command("left-1", "record", on=True)["ok"]
    p.pump(0.1)
    assert p.snapshots["left-1"]["recording"] is True
    assert p.command("left-1", "home")["ok"]
    wait_for(lambda: g.state().referenced and not g.state().moving, "homed")
    time.sleep(0.2)  # the recorder samples at 50 Hz: the homed jaws in it too
    assert p.command("left-1", "record", on=False)["ok"]
    p.pump(0.1)
    snap = p.snapshots["left-1"]
    assert snap["recording"] is False and set(snap["downloads"]) == {"csv", "mcap"}
    base = f"http://127.0.0.1:{server.port}/api/grippers/left-1/recording"
    rows = list(csv.DictReader(io.StringIO(httpx.get(base + ".csv", timeout=5).text)))
    assert rows and {r["gripper"] for r in rows} == {"left_1"}
    assert any(float(r["width_mm"]) > 100 for r in rows)  # the homing is in it
    mcap = httpx.get(base + ".mcap", timeout=5)
    assert mcap.status_code == 200 and mcap.content.startswith(b"\x89MCAP")
    assert httpx.get(base + ".exe", timeout=5).status_code == 404


def test_updates_carry_identity_limits_and_state(opened, serve, page) -> None:
    server = serve({"left": opened("sim://wsg50"), "right": opened("sim://msg-150")})
    p = page(server)
    wait_for(lambda: p.pump(0.05) or len(p.snapshots) == 2, "both grippers")
    left, right = p.snapshots["left"], p.snapshots["right"]
    assert left["info"]["model"] == "WSG 50" and left["info"]["serial"]
    assert left["limits"]["max_width_mm"] == 110.0
    assert right["info"]["family"] == "stepfoc"
    assert right["state"]["force_n"] is None and right["state"]["current_a"] is not None


def test_a_page_closed_right_after_its_command_leaves_nothing_moving(opened, serve, page) -> None:
    """The command still in flight when the page goes is carried out before the deadman looks, so the motion
    it starts is stopped, not left running under a page that is gone."""
    g = opened("sim://wsg50")
    g.home()
    server = serve({"left": g})
    observer = page(server)
    for _ in range(3):
        p = page(server)
        p.send_raw(
            json.dumps({"id": 1, "name": "left", "command": "move", "args": {"width_mm": 0, "speed_mm_s": 5}})
        )
        p.close()
        time.sleep(1.0)
        assert not g.state().moving
        assert observer.snapshots["left"]["controller"] is None
