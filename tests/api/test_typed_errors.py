"""Issue 13 item 7: inputs that raised OverflowError, UnicodeError or a plain ValueError (or silently went
elsewhere) are a LimitError or URLError naming the cause, and nothing is sent. Each failed before."""

from __future__ import annotations

import socket
from typing import Any

import pytest

import grippers
from grippers import LimitError, URLError
from grippers.motions import MotionHandle
from grippers.urls import parse_url

from .conftest import TIME_SCALE


@pytest.mark.parametrize(
    ("url", "match"),
    [
        ("wsg+tcp://a..b", "not a valid host name"),
        ("wsg+tcp://127.0.0.1:0", "port 0"),
        ("wsg+udp://127.0.0.1:0", "port 0"),
    ],
)
def test_malformed_hosts_and_port_zero_are_url_errors(url: str, match: str) -> None:
    with pytest.raises(URLError, match=match):
        parse_url(url)
    with pytest.raises(URLError, match=match):
        grippers.open(url)


@pytest.mark.parametrize(
    ("query", "name"),
    [
        ("timeout=1e10", "timeout"),
        ("timeout=5000", "timeout"),
        ("time_scale=1e300", "time_scale"),
        ("part_width_mm=1e300", "part_width_mm"),
        ("serial=99999999999", "serial"),
    ],
)
def test_out_of_range_settings_are_url_errors_at_open(query: str, name: str) -> None:
    with pytest.raises(URLError, match=rf"{name} must lie within"):
        grippers.open(f"sim://wsg50?{query}")


def test_an_out_of_range_local_port_is_a_url_error_and_nothing_is_sent() -> None:
    listener = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
    listener.bind(("127.0.0.1", 0))
    listener.settimeout(0.2)
    port = listener.getsockname()[1]
    try:
        with pytest.raises(URLError, match="local_port must lie within 0..65535"):
            grippers.open(f"wsg+udp://127.0.0.1:{port}?local_port=70000&timeout=0.2")
        with pytest.raises(socket.timeout):
            listener.recv(100)  # nothing was sent
    finally:
        listener.close()


@pytest.fixture(scope="module")
def wsg() -> Any:
    with grippers.open(f"sim://wsg50?time_scale={TIME_SCALE}") as g:
        g.home()
        yield g


@pytest.mark.parametrize(
    "call",
    [
        lambda g: g.move(10**400),
        lambda g: g.move(0.05, 10**400),
        lambda g: g.grasp(0.04, force=10**400),
        lambda g: g.release(10**400),
        lambda g: g.check(width=10**400),
        lambda g: g.move(0.05, timeout=float("nan")),
        lambda g: g.move(0.05, timeout=-1),
        lambda g: g.stream(rate_hz=0),
        lambda g: g.stream(rate_hz=float("inf")),
        lambda g: g.set_soft_limits(10**400, 0.05),
    ],
)
def test_overflowing_or_meaningless_values_are_limit_errors(wsg: grippers.Gripper, call: Any) -> None:
    before = wsg.state().width
    with pytest.raises(LimitError):
        call(wsg)
    assert wsg.state().width == before and not wsg.state().moving


def test_a_huge_motion_timeout_or_wait_is_no_overflow(wsg: grippers.Gripper) -> None:
    assert wsg.move(0.06, timeout=1e10).width == pytest.approx(0.06, abs=0.002)
    handle = wsg.move(0.05, wait=False)
    assert isinstance(handle, MotionHandle)
    assert handle.wait(1e10).width == pytest.approx(0.05, abs=0.002)


def test_stream_get_takes_any_timeout_without_overflow(wsg: grippers.Gripper) -> None:
    with wsg.stream(rate_hz=100) as stream:
        assert stream.get(timeout=1e10).width >= 0
        with pytest.raises(LimitError, match="timeout"):
            stream.get(timeout=float("nan"))


def test_a_huge_msg_motion_timeout_is_no_overflow() -> None:
    with grippers.open("sim://msg-150?time_scale=200") as g:
        g.home(timeout=1e10)
        assert g.move(0.05, timeout=1e12).width == pytest.approx(0.05, abs=0.002)
