"""Issue 31 §4: the technician's hardware pages say what the software does: the slcan URLs they show parse
to a device path and a bit rate slcan knows, the defaults they name are the profiles' own, and the gs_usb
message they quote is the one the library raises."""

from __future__ import annotations

import re
import tomllib
from pathlib import Path

ROOT = Path(__file__).resolve().parents[2]
MSG_PAGE = (ROOT / "docs" / "getting-started-msg.md").read_text()
SECTION = " ".join(MSG_PAGE[MSG_PAGE.index("## The adapter in detail") :].split())  # lines joined
TROUBLE = " ".join((ROOT / "docs" / "troubleshooting.md").read_text().split())


def test_the_slcan_urls_shown_parse_to_a_device_path_and_a_bitrate_slcan_knows() -> None:
    from can.interfaces.slcan import slcanBus

    from grippers.drivers.urls import parse_url

    urls = re.findall(r"'((?:stepfoc\+)?can://slcan/[^' ]+)'", SECTION)
    assert len(urls) >= 2
    for url in urls:
        parsed = parse_url(url, bare_family="stepfoc")
        assert parsed.interface == "slcan" and parsed.channel.startswith("/dev/tty"), url
        assert int(parsed.params["bitrate"]) in slcanBus._BITRATES, url
    for rate in ("10k, 20k, 50k, 100k, 125k, 250k, 500k, 750k and 1M",):
        assert rate in SECTION and rate in TROUBLE
    assert sorted(slcanBus._BITRATES) == sorted(
        [10_000, 20_000, 50_000, 83_300, 100_000, 125_000, 250_000, 500_000, 750_000, 1_000_000]
    )  # 83.3k is python-can's own extra; the pages name the standard ones


def test_the_default_bitrates_named_are_the_profiles() -> None:
    from grippers.profiles import load_profile

    assert load_profile("msg-100").transport.can_bitrate == 1_000_000
    assert load_profile("wsg50").transport.can_bitrate == 500_000
    assert "1000000 for an MSG" in SECTION and "500000 for a WSG" in SECTION


def test_the_usb_extra_and_its_message_are_as_the_pages_say() -> None:
    from grippers.drivers.canlink import NEEDS_EXTRA

    extras = tomllib.loads((ROOT / "pyproject.toml").read_text())["project"]["optional-dependencies"]
    assert any("gs-usb" in dep for dep in extras["usb"])
    packages, extra = NEEDS_EXTRA["gs_usb"]
    quoted = f"the gs_usb interface needs {packages}: pip install '{extra}'"
    assert quoted in SECTION and quoted in TROUBLE


def test_the_troubleshooting_page_links_to_the_section() -> None:
    assert "getting-started-msg.md#the-adapter-in-detail" in TROUBLE
