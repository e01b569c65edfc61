"""Issue 31 §1: a serial-line CAN adapter's device path keeps its leading slash, a network channel gets none.

The documented ``stepfoc+can://slcan/dev/ttyACM0?node=0`` (docs/getting-started-msg.md) opened the relative
path ``dev/ttyACM0``; only ``slcan//dev/ttyACM0`` worked, and ``grippers probe can://slcan/dev/ttyACM0``
failed the same way. Nothing is opened here: the parsed channel is what python-can would be handed.
"""

from __future__ import annotations

import can.interfaces
import pytest

from grippers.cli.probe_targets import expand
from grippers.drivers.stepfoc.can_protocol import parse_can_url
from grippers.drivers.urls import SERIAL_CHANNEL_INTERFACES
from grippers.urls import parse_url

# Every python-can interface whose channel is a serial port (pyserial opens it).
SERIAL_LIKE = ["slcan", "serial", "seeedstudio", "robotell"]


def test_the_serial_like_interfaces_are_the_ones_python_can_names() -> None:
    assert set(SERIAL_LIKE) == SERIAL_CHANNEL_INTERFACES
    assert set(can.interfaces.BACKENDS) >= SERIAL_CHANNEL_INTERFACES


@pytest.mark.parametrize("interface", SERIAL_LIKE)
@pytest.mark.parametrize("scheme", ["stepfoc+can", "wsg+can", "can"])
@pytest.mark.parametrize(
    ("written", "opened"),
    [
        ("dev/ttyACM0", "/dev/ttyACM0"),  # the documented form
        ("/dev/ttyACM0", "/dev/ttyACM0"),  # the doubled slash keeps working
        ("dev/ttyACM0@115200", "/dev/ttyACM0@115200"),  # slcan's own @baud suffix
        ("dev/serial/by-id/usb-CANable_8c005eb-if00", "/dev/serial/by-id/usb-CANable_8c005eb-if00"),
        ("COM3", "COM3"),  # Windows
        ("ttyACM0", "ttyACM0"),
        ("./ttyACM0", "./ttyACM0"),  # a relative path, asked for
        ("socket://127.0.0.1:4000", "socket://127.0.0.1:4000"),  # a pyserial URL
    ],
)
def test_a_serial_like_channel_is_a_device_path(
    interface: str, scheme: str, written: str, opened: str
) -> None:
    url = f"{scheme}://{interface}/{written}?node=0"
    assert parse_url(url, bare_family="stepfoc").channel == opened


@pytest.mark.parametrize("interface", SERIAL_LIKE)
def test_the_driver_and_the_probe_open_the_absolute_path(interface: str) -> None:
    assert parse_can_url(f"stepfoc+can://{interface}/dev/ttyACM0?node=0")[1] == "/dev/ttyACM0"
    plan = expand(f"can://{interface}/dev/ttyACM0")
    assert plan.candidates
    for candidate in plan.candidates:
        assert candidate.location["channel"] == "/dev/ttyACM0", candidate.url
        assert parse_url(candidate.url).channel == "/dev/ttyACM0"


@pytest.mark.parametrize(
    ("interface", "channel"),
    [
        ("socketcan", "can0"),
        ("socketcan", "vcan0"),
        ("udp_multicast", "239.74.163.2"),
        ("udp_multicast", "ff15::7079:1"),
        ("virtual", "grippers-sim-1"),
        ("virtual", "a/b"),  # a virtual channel is a name, slashes and all
        ("pcan", "PCAN_USBBUS1"),
        ("kvaser", "0"),
        ("vector", "0"),
        ("ixxat", "0"),
        ("gs_usb", "canable gs_usb"),
        ("socketcand", "can0"),
        ("neovi", "1"),
        ("nican", "CAN0"),
        ("systec", "0"),
        ("usb2can", "ED000200"),
        ("cantact", "0"),
        ("canalystii", "0"),
    ],
)
def test_a_network_channel_gets_no_slash(interface: str, channel: str) -> None:
    for scheme in ("stepfoc+can", "wsg+can"):
        assert parse_url(f"{scheme}://{interface}/{channel}").channel == channel


def test_the_documented_slcan_urls_open_an_absolute_device_path() -> None:
    """The docs' own slcan URLs (docs/getting-started-msg.md), read as grippers.open reads them."""
    import re
    from pathlib import Path

    root = Path(__file__).resolve().parents[2]
    text = "\n".join(
        p.read_text(encoding="utf-8") for p in [root / "README.md", *(root / "docs").glob("*.md")]
    )
    urls = re.findall(r"(?:stepfoc|wsg)\+can://(?:slcan|serial|seeedstudio|robotell)/[^\s`'\")]+", text)
    assert urls, "the docs show a serial-line CAN adapter's URL"
    for url in urls:
        channel = parse_url(url).channel
        assert channel is not None and channel.startswith("/dev/"), (url, channel)
