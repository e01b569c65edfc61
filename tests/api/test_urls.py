"""The URL grammar, and the precedence of profile < query < keyword overrides."""

from __future__ import annotations

import pytest

from grippers import URLError
from grippers.settings import Settings
from grippers.urls import parse_url


@pytest.mark.parametrize(
    ("url", "fields"),
    [
        (
            "wsg+tcp://192.168.1.20",
            {"family": "wsg", "transport": "tcp", "host": "192.168.1.20", "port": None},
        ),
        (
            "wsg+udp://10.0.0.2:1500?local_port=0",
            {"transport": "udp", "port": 1500, "params": {"local_port": "0"}},
        ),
        (
            "wsg+serial:///dev/ttyUSB0?baudrate=9600",
            {"serial_port": "/dev/ttyUSB0", "params": {"baudrate": "9600"}},
        ),
        ("wsg+serial://socket://127.0.0.1:4000", {"serial_port": "socket://127.0.0.1:4000"}),
        ("wsg+can://socketcan/can0?send_id=0x10", {"interface": "socketcan", "channel": "can0"}),
        (
            "stepfoc+can://udp_multicast/239.74.163.2?node=3",
            {"channel": "239.74.163.2", "params": {"node": "3"}},
        ),
        ("sim://msg-150?part_width_mm=40", {"family": "sim", "profile": "msg-150"}),
        ("sim://", {"family": "sim", "profile": None}),
    ],
)
def test_parse(url: str, fields: dict) -> None:
    parsed = parse_url(url)
    for key, value in fields.items():
        assert getattr(parsed, key) == value


@pytest.mark.parametrize(
    "url",
    [
        "wsg50",
        "wsg+ftp://x",
        "tcp+wsg://x",
        "wsg+tcp://:1000",
        "wsg+tcp://h:99999",
        "wsg+can://socketcan",
        "wsg+serial://",
    ],
)
def test_malformed_urls_are_refused(url: str) -> None:
    with pytest.raises(URLError):
        parse_url(url)


def test_overrides_win_over_query_and_unknown_settings_are_refused() -> None:
    s = Settings("wsg+tcp://h?timeout=3", {"timeout": "3", "tyop": "1"}, {"timeout": 0.5})
    assert s.float("timeout", 1.0) == 0.5
    assert s.int("node", 7) == 7  # not given: the profile's default
    with pytest.raises(URLError, match="tyop"):
        s.finish()


def test_open_refuses_unknown_setting() -> None:
    import grippers

    with pytest.raises(URLError, match="bogus"):
        grippers.open("sim://wsg50", bogus=1)
