"""Issue 31 §1: a misspelt URL setting is a URLError before any I/O, for every family and scheme.

``stepfoc+can://…?nod=3`` on a silent bus was reported as "poll: no reply within …" after the timeout: the
backend opened the bus and polled before the leftover ``nod`` was looked at. Here the connectors are replaced
by ones that fail the test if reached, so the error must come before anything is opened.
"""

from __future__ import annotations

import uuid
from typing import Any

import pytest

import grippers
from grippers import URLError
from grippers.backends import stepfoc as stepfoc_backend
from grippers.drivers.wsg.client import WsgClient


class Reached(AssertionError):
    """A connector ran: I/O would have happened before the misspelt setting was refused."""


def _no_io(*_args: Any, **_kwargs: Any) -> Any:
    raise Reached("opened a connection before refusing the misspelt setting")


@pytest.fixture
def no_io(monkeypatch: pytest.MonkeyPatch) -> None:
    for name in ("tcp", "udp", "serial", "can"):
        monkeypatch.setattr(WsgClient, name, staticmethod(_no_io))
    monkeypatch.setattr(stepfoc_backend, "CanLink", _no_io)
    monkeypatch.setattr(stepfoc_backend, "UartLink", _no_io)
    try:
        from grippers.remote import client as remote_client
    except ImportError:  # pragma: no cover - the remote extra is part of the test environment
        return
    monkeypatch.setattr(remote_client, "RemoteDevice", _no_io)


@pytest.mark.parametrize(
    ("url", "typo", "meant"),
    [
        ("wsg+tcp://127.0.0.1:1?timout=1", "timout", "timeout"),
        ("wsg+udp://127.0.0.1:1?local_prot=5", "local_prot", "local_port"),
        ("wsg+serial:///dev/ttyUSB0?baudrat=115200", "baudrat", "baudrate"),
        ("wsg+can://virtual/x?send_ld=0x10", "send_ld", "send_id"),
        ("stepfoc+can://virtual/x?nod=3", "nod", "node"),
        ("stepfoc+can://slcan/dev/ttyACM0?nod=3", "nod", "node"),
        ("stepfoc+serial:///dev/ttyACM0?baud=256000", "baud", "baudrate"),
        ("stepfoc+can://virtual/x?node=3&reconect=true", "reconect", "reconnect"),
        ("zenoh://arm?connect=tcp/127.0.0.1:1&lable=x", "lable", "label"),
    ],
)
def test_a_misspelt_setting_is_refused_before_any_io(no_io: None, url: str, typo: str, meant: str) -> None:
    with pytest.raises(URLError) as caught:
        grippers.open(url)
    text = str(caught.value)
    assert f"unknown setting(s) {typo}" in text
    assert f"did you mean {meant}?" in text
    assert meant in text.rpartition("this backend takes:")[2]  # and every known one is listed


def test_a_misspelt_keyword_is_refused_before_any_io(no_io: None) -> None:
    with pytest.raises(URLError, match="unknown setting.*nod.*did you mean node"):
        grippers.open("stepfoc+can://virtual/x", nod=3)


def test_the_reconnection_settings_are_still_known(no_io: None) -> None:
    """Taken after the device answered, they must not be taken for typos before it."""
    with pytest.raises(Reached):
        grippers.open("stepfoc+can://virtual/x?node=3&reconnect=true&heartbeat_s=0.5")


@pytest.mark.parametrize("profile", ["wsg50", "msg-150"])
def test_a_misspelt_setting_of_a_simulated_gripper(profile: str) -> None:
    with pytest.raises(URLError, match="unknown setting.*part_widht_mm.*did you mean part_width_mm"):
        grippers.open(f"sim://{profile}?part_widht_mm=40")


def test_on_a_silent_bus_the_typo_is_said_at_once_not_a_poll_timeout() -> None:
    """A real, empty bus: nothing answers node 3, so reaching the poll raised GripperTimeout "poll: no reply"
    (not a URLError) after the timeout."""
    url = f"stepfoc+can://virtual/silent-{uuid.uuid4().hex[:8]}?nod=3&timeout=0.5"
    with pytest.raises(URLError, match="unknown setting.*nod"):
        grippers.open(url)
