"""Edge cases of the vendor-neutral layer found in review: each test failed before its fix.

Everything runs through ``grippers.open`` against the simulators over real transports (loopback TCP, a
pseudo-terminal, a python-can virtual bus); the simulators' own hooks inject the faults.
"""

from __future__ import annotations

import time
import uuid
from pathlib import Path

import pytest

import grippers
from grippers import (
    CommandFailed,
    ConnectionLost,
    FastStopActive,
    GraspState,
    GripperTimeout,
    LimitError,
    ProfileError,
    URLError,
)
from grippers.backends.stepfoc import StepfocBackend
from grippers.settings import Settings
from grippers.urls import parse_url
from tests.simhold import MSG_CREEP_S, held, step_until, under_way

from .conftest import ROOT, TIME_SCALE


def _profile_file(tmp_path: Path, base: str, name: str, extra: str) -> Path:
    """A copy of a shipped profile under a new name with ``extra`` TOML appended (tables only)."""
    text = (ROOT / "profiles" / f"{base}.toml").read_text(encoding="utf-8")
    text = text.replace(f'name = "{base}"', f'name = "{name}"', 1)
    text = "\n".join(line for line in text.splitlines() if not line.startswith("aliases"))
    path = tmp_path / f"{name}.toml"
    path.write_text(text + "\n" + extra, encoding="utf-8")
    return path


# --- MSG motions that are stopped, closed under, or hit a device error ------------------------------------


@pytest.mark.parametrize("transport", ["can", "pty"])
def test_msg_cancel_ends_the_wait_instead_of_running_into_the_timeout(transport: str) -> None:
    # Detection stays 0 (moving) after the action bit is cleared, so waiting for "not moving" never ended.
    with grippers.open(f"sim://msg-150?time_scale=8&transport={transport}") as g:
        g.home()
        start = g.state().width
        with held(g, creep=MSG_CREEP_S) as clock:  # still moving at the cancel (issue 33 §5)
            handle = g.move(g.limits.max_width, g.limits.min_speed, wait=False)
            step_until(clock, under_way(g, start), "the move under way")
            handle.cancel()
        with pytest.raises(CommandFailed, match=r"aborted by cancel\(\)"):
            handle.wait(3.0)  # GripperTimeout here before the fix (the motion takes ~5 s)
        handle.join(3.0)  # the backend's wait ends too, well before the motion's own timeout
        assert not handle._busy()
        deadline = time.monotonic() + 3.0
        while (st := g.state()).moving:  # decelerating
            assert time.monotonic() < deadline
            time.sleep(0.005)
        assert g.limits.min_width < st.width < g.limits.max_width


def test_msg_close_during_a_motion_on_a_shared_bus_ends_the_motion_thread() -> None:
    # With a second node keeping the bus open, the motion thread polled on until its motion timeout, and
    # close() gave up joining it after 5 s.
    backend = StepfocBackend()
    profile = grippers.load_profile("msg-150")
    channel = f"review-{uuid.uuid4().hex[:8]}"
    settings = Settings("test", {"time_scale": "5"}, {})
    server = backend.serve(
        [backend.sim_model(profile, 0, None), backend.sim_model(profile, 1, None)],
        f"can://virtual/{channel}",
        settings,
    )
    try:
        with grippers.open(f"stepfoc+can://virtual/{channel}?node=1") as other:
            g = grippers.open(f"stepfoc+can://virtual/{channel}?node=0")
            g.home(timeout=120)
            handle = g.move(g.limits.max_width, g.limits.min_speed, wait=False)  # ~8 s at time scale 5
            time.sleep(0.05)
            g.close()
            with pytest.raises(ConnectionLost, match="closed during the motion"):
                handle.wait(0)
            assert other.state().referenced is False  # the shared bus still serves the other node
    finally:
        server.close()


def test_msg_device_error_during_a_motion_is_command_failed_not_a_timeout() -> None:
    with grippers.open("sim://msg-150?time_scale=8") as g:
        g.home()
        start = g.state().width
        with held(g, creep=MSG_CREEP_S) as clock:  # still moving at the error (issue 33 §5)
            handle = g.move(g.limits.max_width, g.limits.min_speed, wait=False)
            step_until(clock, under_way(g, start), "the move under way")
            g.simulator.models[0].temperature_error = True  # the driver stops the motor
        with pytest.raises(CommandFailed, match="temperature"):
            handle.wait(3.0)


# --- limits ----------------------------------------------------------------------------------------------


def test_default_speed_and_force_respect_the_safety_limits(tmp_path: Path) -> None:
    # wsg50's defaults are 100 mm/s and 40 N; a safety section below them was bypassed by calls without them.
    safety = "[safety]\nmax_speed_mm_s = 50.0\nmax_force_n = 20.0\n"
    path = _profile_file(tmp_path, "wsg50", "wsg50-safe", safety)
    with grippers.open(f"sim://?time_scale={TIME_SCALE}", profile=str(path)) as g:
        _, speed, force = g.check()
        assert speed == pytest.approx(0.05)
        assert force == pytest.approx(20.0)


def test_msg_force_limits_follow_the_current_limit(tmp_path: Path) -> None:
    # 500 mA at 40 N/A is 20 N: a 30 N request was accepted and silently became 20 N.
    path = _profile_file(tmp_path, "msg-150", "msg-150-soft", "")
    path.write_text(
        path.read_text(encoding="utf-8").replace("max_current_ma = 1000    #", "max_current_ma = 500    #"),
        encoding="utf-8",
    )
    with grippers.open(f"sim://?time_scale={TIME_SCALE}", profile=str(path)) as g:
        assert g.limits.max_force == pytest.approx(20.0)
        with pytest.raises(LimitError, match="force"):
            g.grasp(0.03, force=30)


def test_msg_inside_grip_release_defaults_to_closing(tmp_path: Path) -> None:
    path = _profile_file(tmp_path, "msg-150", "msg-150-inside", "")
    text = path.read_text(encoding="utf-8")
    path.write_text(text.replace("grasp_travel_mm = 10.0", "grasp_travel_mm = 10.0\ninside_grip = true"))
    with grippers.open(f"sim://?time_scale={TIME_SCALE}", profile=str(path)) as g:
        g.home()
        g.move(g.limits.max_width / 2)
        assert g.release().width == pytest.approx(g.limits.min_width, abs=0.002)


# --- fast stop -------------------------------------------------------------------------------------------


def test_fast_stop_refuses_motion_even_when_its_reply_is_lost() -> None:
    with grippers.open(f"sim://wsg50?time_scale={TIME_SCALE}", timeout=0.3) as g:
        g.home()
        g.simulator.faults.drop_replies(1)
        with pytest.raises(GripperTimeout):
            g.fast_stop()
        with pytest.raises(FastStopActive):
            g.move(g.limits.max_width / 2)


# --- URLs and settings -----------------------------------------------------------------------------------


@pytest.mark.parametrize("url", ["wsg+tcp://[::1", "sim://[x", "wsg+can://[/can0", "wsg+udp://[zz]:1500"])
def test_unbalanced_ipv6_brackets_are_url_errors(url: str) -> None:
    with pytest.raises(URLError):
        parse_url(url)


def test_ipv6_zone_is_unescaped_for_the_socket() -> None:
    u = parse_url("wsg+tcp://[fe80::1%25eth0]:1000")
    assert (u.host, u.port) == ("fe80::1%eth0", 1000)


def test_pyserial_url_with_its_own_query_ends_with_an_empty_query_of_ours() -> None:
    # Our parameters follow the LAST "?": a trailing "?" hands the whole pyserial URL over untouched.
    u = parse_url("wsg+serial://socket://127.0.0.1:4000?logging=debug?")
    assert (u.serial_port, u.params) == ("socket://127.0.0.1:4000?logging=debug", {})
    u = parse_url("wsg+serial://socket://127.0.0.1:4000?logging=debug?baudrate=9600")
    assert (u.serial_port, u.params) == ("socket://127.0.0.1:4000?logging=debug", {"baudrate": "9600"})


@pytest.mark.parametrize(
    "query",
    [
        "timeout=nan",  # a nan deadline never passes: a wait without end
        "timeout=0",
        "time_scale=0",
        "time_scale=inf",
        "clamping_travel_mm=nan",
    ],
)
def test_non_finite_or_non_positive_settings_are_url_errors(query: str) -> None:
    with pytest.raises(URLError, match=query.split("=")[0]):
        grippers.open(f"sim://wsg50?{query}")


@pytest.mark.parametrize("query", ["node=99", "part_width_mm=-5", "time_scale=-1"])
def test_simulator_parameters_refused_as_url_errors(query: str) -> None:
    with pytest.raises(URLError):
        grippers.open(f"sim://msg-150?{query}")


def test_profile_keyword_wins_over_query_and_may_be_a_loaded_profile() -> None:
    with grippers.open(f"sim://?profile=wsg25&time_scale={TIME_SCALE}", profile="wsg32") as g:
        assert g.profile.name == "wsg32"
    with grippers.open(f"sim://?time_scale={TIME_SCALE}", profile=grippers.load_profile("msg-100")) as g:
        assert g.profile.name == "msg-100"


def test_sim_url_profile_and_a_different_profile_keyword_conflict() -> None:
    with pytest.raises(ProfileError, match="wsg25"):
        grippers.open("sim://wsg50", profile="wsg25")


# --- profiles --------------------------------------------------------------------------------------------


def test_a_broken_user_profile_does_not_break_lookups(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    (tmp_path / "broken.toml").write_text('name = "broken"\nfamily = "wsg"\n', encoding="utf-8")
    monkeypatch.setenv("GRIPPERS_PROFILE_PATH", str(tmp_path))
    with pytest.raises(ProfileError, match="no profile named 'nope'"):
        grippers.load_profile("nope")
    # A WSG reached by URL finds its profile from the device type (a lookup over every profile).
    with grippers.open(f"sim://wsg32?time_scale={TIME_SCALE}") as sim, grippers.open(sim.simulator.url) as g:
        assert g.profile.name == "wsg32"
    with pytest.raises(ProfileError, match="broken"):
        grippers.profiles.list_profiles(strict=True)  # the strict listing still reports it
    scan = grippers.profiles.scan_profiles()  # what `profiles list` shows: the rest, and the bad file named
    assert "wsg50" in {p.name for p in scan.profiles}
    assert [f for f, _ in scan.problems] == [str(tmp_path / "broken.toml")]


def test_grasp_state_after_a_cancelled_msg_grasp_is_not_holding() -> None:
    with grippers.open("sim://msg-150?time_scale=8&part_width_mm=20") as g:
        g.home()
        g.release()
        start = g.state().width
        with held(g, creep=MSG_CREEP_S) as clock:  # still closing at the cancel (issue 33 §5)
            handle = g.grasp(0.02, g.limits.min_speed, wait=False)
            step_until(clock, under_way(g, start), "the grasp under way")
            handle.cancel()
        with pytest.raises(CommandFailed, match=r"aborted by cancel\(\)"):
            handle.wait(3.0)
        handle.join(3.0)
        assert g.state().grasp is not GraspState.HOLDING
