"""Issue 42 §4: the panel in a real browser (Debian's chromium driven by Playwright), against simulators.

Every assertion about the device reads the simulator's own model (``g.simulator.model``), not the page."""

from __future__ import annotations

import os
import re
import time
from pathlib import Path
from typing import Any

import pytest

from .browser import ENV, SKIP_REASON, browser_only
from .conftest import wait_for

pytestmark = browser_only
if os.environ.get(ENV) != "1":
    pytest.skip(SKIP_REASON, allow_module_level=True)
expect = pytest.importorskip("playwright.sync_api").expect


def model(g: Any) -> Any:
    """The simulator's model, brought up to its clock (a state query advances it)."""
    g.state()
    return g.simulator.model


def test_the_page_loads_without_console_errors(opened, serve, tab) -> None:
    server = serve({"left": opened("sim://wsg50"), "right": opened("sim://msg-150")})
    t = tab(server.url)
    for name in ("left", "right"):
        card = t.card(name)
        for button in (
            "Home",
            "Move",
            "Grasp",
            "Release",
            "Stop",
            "Fast stop",
            "Acknowledge",
            "-10 mm",
            "-1 mm",
            "+1 mm",
            "+10 mm",
            "Take control",
            "Record",
        ):
            expect(card.get_by_role("button", name=button, exact=True)).to_be_visible()
        for label in ("Width (mm)", "Force (N)", "Speed (mm/s)"):
            expect(card.get_by_label(label, exact=True)).to_be_editable()
        expect(card.get_by_role("img", name="Chart")).to_be_visible()
        expect(card.get_by_role("button", name="Record")).to_have_attribute("aria-pressed", "false")
        expect(card.get_by_role("link", name="Download CSV")).to_have_count(0)
    expect(t.readout("left", "Width")).to_have_text(re.compile(r"^\d+\.\d mm$"))
    expect(t.readout("left", "Force")).to_have_text(re.compile(r"^\d+\.\d N$"))
    expect(t.readout("right", "Force")).to_have_text(re.compile(r"^\d+\.\d\d A$"))  # the MSG reports current
    expect(t.readout("left", "Faults")).to_have_text("none")
    expect(t.readout("left", "Speed")).to_have_text(re.compile(r"^\d+\.\d mm/s$"))
    expect(t.readout("left", "Temperature")).to_have_text(re.compile(r"^\d+\.\d °C$"))  # the WSG reports it
    expect(t.readout("right", "Temperature")).to_have_text(re.compile(r"^\d+\.\d °C$"))  # the MSG's driver
    expect(t.card("left").get_by_label("Width (mm)", exact=True)).to_have_attribute("max", "110")
    expect(t.card("left")).to_contain_text("WSG 50")
    expect(t.card("left")).to_contain_text("serial 12345")
    time.sleep(0.5)
    assert t.errors == []


def test_the_live_width_follows_a_motion_started_from_python(opened, serve, tab) -> None:
    g = opened("sim://wsg50")
    g.home()
    server = serve({"left": g})
    t = tab(server.url)
    width = t.readout("left", "Width")
    expect(width).to_have_text("110.0 mm")
    g.move(0.010, 0.05, wait=False)  # 2 s at real time
    seen = set()
    deadline = time.monotonic() + 10
    while time.monotonic() < deadline:
        text = width.text_content()
        seen.add(text)
        if text == "10.0 mm":
            break
        time.sleep(0.02)
    assert "10.0 mm" in seen
    between = [float(s.split()[0]) for s in seen if s and 10.5 < float(s.split()[0]) < 109.5]
    assert len(between) >= 10, seen  # the page followed the motion, not only its end
    expect(t.readout("left", "State")).to_have_text("idle")


def test_each_button_acts_on_the_simulator(opened, serve, tab) -> None:
    g = opened("sim://wsg50?time_scale=10")
    t = tab(serve({"left": g}).url)
    t.press("left", "Home")
    wait_for(lambda: model(g).referenced and not g.state().moving, "Home referenced the axis")
    t.fill("left", "Speed (mm/s)", 200)
    t.fill("left", "Width (mm)", 40)
    t.press("left", "Move")
    wait_for(lambda: abs(model(g).position - 40.0) < 0.2 and not g.state().moving, "Move to 40 mm")
    for button, target in (("-10 mm", 30.0), ("-1 mm", 29.0), ("+1 mm", 30.0), ("+10 mm", 40.0)):
        t.press("left", button)
        wait_for(lambda target=target: abs(model(g).position - target) < 0.2 and not g.state().moving, button)
        expect(t.readout("left", "Width")).to_have_text(f"{target:.1f} mm")
    g.simulator.place_part(30.0)
    t.fill("left", "Width (mm)", 30)
    t.fill("left", "Force (N)", 20)
    t.press("left", "Grasp")
    wait_for(lambda: model(g).holding, "Grasp holds the part")
    expect(t.readout("left", "State")).to_have_text("holding")
    t.press("left", "Release")
    wait_for(lambda: not model(g).holding and model(g).position > 100.0, "Release opened")
    g.simulator.remove_part()
    t.fill("left", "Speed (mm/s)", 10)
    t.fill("left", "Width (mm)", 0)
    t.press("left", "Move")
    wait_for(lambda: g.state().moving, "moving")
    t.press("left", "Stop")
    wait_for(lambda: not g.state().moving, "Stop stopped it")
    assert model(g).position > 5.0
    t.press("left", "Fast stop")
    wait_for(lambda: model(g).fast_stop, "Fast stop")
    expect(t.readout("left", "Faults")).to_have_text("fast_stop")
    t.press("left", "Acknowledge")
    wait_for(lambda: not model(g).fast_stop, "Acknowledge")
    expect(t.readout("left", "Faults")).to_have_text("none")
    record = t.card("left").get_by_role("button", name="Record")
    record.click()
    expect(record).to_have_attribute("aria-pressed", "true")
    time.sleep(0.3)
    record.click()
    expect(record).to_have_attribute("aria-pressed", "false")
    for label, check in (("Download CSV", b"t_s,gripper,"), ("Download MCAP", b"\x89MCAP")):
        with t.page.expect_download() as download:
            t.card("left").get_by_role("link", name=label).click()
        assert Path(download.value.path()).read_bytes().startswith(check)
    assert t.errors == []


def test_a_refused_command_shows_its_message_until_its_condition_ends(opened, serve, tab) -> None:
    g = opened("sim://wsg50?time_scale=10")
    t = tab(serve({"left": g}).url)
    t.fill("left", "Width (mm)", 400)
    t.press("left", "Move")
    expect(t.alert("left")).to_have_text("move: width 400 mm is outside 0..110 mm")
    t.press("left", "Fast stop")
    # The Fast stop succeeded: the old error is gone (the alert may say the fast stop's own fault by then) ...
    expect(t.alert("left")).not_to_contain_text("outside")
    t.fill("left", "Width (mm)", 40)
    t.press("left", "Move")
    expect(t.alert("left")).to_contain_text("move: fast stop is active")
    g.acknowledge()  # ... and this one ends with its condition, whoever ends it
    expect(t.alert("left")).to_have_text("")
    t.press("left", "Move")
    expect(t.alert("left")).to_have_text(
        "move refused: the gripper is not referenced; call home() first (E_NOT_INITIALIZED)"
    )


def test_two_pages_and_control(opened, serve, tab) -> None:
    g = opened("sim://wsg50?time_scale=10")
    server = serve({"left": g})
    a, b = tab(server.url), tab(server.url)
    expect(a.card("left")).to_contain_text("observing (nobody controls)")
    a.press("left", "Home")
    expect(a.card("left")).to_contain_text("this page controls")
    expect(b.card("left")).to_contain_text("page 1 at 127.0.0.1 controls")
    wait_for(lambda: model(g).referenced and not g.state().moving, "homed")
    b.fill("left", "Width (mm)", 20)
    b.press("left", "Move")
    expect(b.alert("left")).to_contain_text("page 1 at 127.0.0.1 controls this gripper; press Take control")
    assert abs(model(g).position - 110.0) < 0.2  # refused: nothing moved
    a.fill("left", "Speed (mm/s)", 5)
    a.fill("left", "Width (mm)", 0)
    a.press("left", "Move")
    wait_for(lambda: g.state().moving, "page 1's move")
    b.press("left", "Stop")  # any page may stop
    wait_for(lambda: not g.state().moving, "stopped by page 2")
    b.press("left", "Take control")
    expect(b.card("left")).to_contain_text("this page controls")
    expect(a.card("left")).to_contain_text("page 2 at 127.0.0.1 controls")
    b.press("left", "Move")
    wait_for(lambda: abs(model(g).position - 20.0) < 0.2 and not g.state().moving, "page 2 moved it")
    assert a.errors == [] and b.errors == []


def test_a_page_closed_mid_motion_stops_the_jaws(opened, serve, tab) -> None:
    g = opened("sim://wsg50")
    g.home()
    server = serve({"left": g})
    t = tab(server.url)
    t.fill("left", "Speed (mm/s)", 5)
    t.fill("left", "Width (mm)", 0)
    t.press("left", "Move")
    wait_for(lambda: g.state().moving, "moving")
    t.page.close()
    closed = time.monotonic()
    wait_for(lambda: not g.state().moving, "stopped once the page closed", timeout=5)
    assert time.monotonic() - closed < 1.5  # the 1 s, and a state read and a stop on a busy machine
    assert model(g).position > 50.0


def test_a_token_is_required_off_loopback(opened, serve, tab) -> None:
    server = serve({"left": opened("sim://wsg50")}, listen="0.0.0.0:0")
    bare = f"http://127.0.0.1:{server.port}/"
    t = tab(bare, wait_connected=False)
    assert t.response.status == 401
    expect(t.page.get_by_role("region", name="left")).to_have_count(0)
    t = tab(f"{bare}?token=wrong", wait_connected=False)
    assert t.response.status == 403
    t = tab(f"{bare}?token={server.token}")  # the printed URL: the page, its assets and its WebSocket
    expect(t.readout("left", "Width")).to_have_text(re.compile(r" mm$"))
    t.page.goto(bare)  # the cookie it set carries the token from now on
    expect(t.readout("left", "Width")).to_have_text(re.compile(r" mm$"))
    assert t.errors == []


def test_four_grippers_on_one_page(opened, serve, tab, tmp_path: Path) -> None:
    named = {
        "left": opened("sim://wsg50?time_scale=10"),
        "right": opened("sim://msg-150?time_scale=10"),
        "hand": opened("sim://robotiq-2f85?time_scale=10"),
        "small": opened("sim://wsg25?time_scale=10"),
    }
    server = serve(named)
    t = tab(server.url)
    for name in named:
        t.press(name, "Home")
    for name, g in named.items():
        wait_for(lambda g=g: g.state().referenced and not g.state().moving, f"{name} homed", timeout=30)
        expect(t.readout(name, "State")).to_have_text(re.compile(r"^idle"))
        expect(t.readout(name, "Width")).to_have_text(f"{g.state().width * 1000:.1f} mm")
    t.fill("hand", "Width (mm)", 40)
    t.press("hand", "Move")
    wait_for(lambda: abs(named["hand"].state().width - 0.040) < 1e-3, "the 2F-85 moved")
    expect(t.readout("hand", "Width")).to_have_text(re.compile(r"^(39\.\d|40\.\d) mm$"))
    expect(t.readout("hand", "Temperature")).to_be_hidden()  # the Robotiq reports none
    expect(t.readout("hand", "Speed")).to_have_text("not reported")
    time.sleep(1.5)  # some history on the charts
    # GRIPPERS_PANEL_SCREENSHOT=docs/images/panel.png renews the documentation's picture
    shot = os.environ.get("GRIPPERS_PANEL_SCREENSHOT") or str(tmp_path / "panel.png")
    t.page.screenshot(path=shot, full_page=True)
    assert Path(shot).stat().st_size > 10_000
    assert t.errors == []


def test_a_zenoh_gripper(opened, serve, tab) -> None:
    pytest.importorskip("zenoh")
    from ..remote.conftest import ServeProcess

    served = ServeProcess("cell=sim://wsg50?time_scale=10")
    try:
        url = served.urls["cell"]
        g = opened(url)
        t = tab(serve({"cell": g}).url)
        expect(t.card("cell")).to_contain_text("WSG 50")
        t.press("cell", "Home")
        wait_for(lambda: g.state().referenced and not g.state().moving, "homed over Zenoh")
        expect(t.readout("cell", "Width")).to_have_text("110.0 mm")
        g.release_control()  # the panel's lease freed: another client takes it
        other = opened(url + "&label=robot-program")
        other.acquire_control()
        t.fill("cell", "Width (mm)", 30)
        t.press("cell", "Move")
        expect(t.alert("cell")).to_contain_text("robot-program")  # the lease's holder, as the library says
        t.press("cell", "Stop")  # never refused
        expect(t.alert("cell")).to_have_text("")
        other.release_control()
        t.press("cell", "Move")
        wait_for(
            lambda: abs(other.state().width - 0.030) < 5e-4 and not other.state().moving, "moved over Zenoh"
        )
        assert t.errors == []
    finally:
        served.close()


def test_a_lost_device_and_its_return(opened, serve, tab) -> None:
    from ..reconnect.conftest import FAST, Restartable, free_port

    sim = Restartable("wsg", "--listen", f"tcp://127.0.0.1:{free_port()}", "--time-scale", "20")
    try:
        g = opened(f"{sim.url}?reconnect=true&{FAST}")
        t = tab(serve({"left": g}).url)
        connection = t.card("left").locator(".connection")
        expect(connection).to_have_text("connected")
        sim.kill()
        expect(connection).to_have_text("connection lost")
        expect(t.alert("left")).to_contain_text("connection lost")
        sim.start()
        expect(connection).to_have_text("connected", timeout=20_000)
        expect(t.alert("left")).to_have_text("")
        expect(t.readout("left", "Width")).to_have_text(re.compile(r" mm$"))
    finally:
        sim.close()
