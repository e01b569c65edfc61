"""A served MSG whose model was assumed (opened without a profile) warns a ``zenoh://`` client at open, as a
local open warns (issue 22 §1: never a silent assumption, at every entry point)."""

from __future__ import annotations

import re
import warnings

import pytest

import grippers
from grippers.errors import ProfileAssumed

from ..conftest import SimProcess
from .conftest import ServeProcess, sim

pytestmark = pytest.mark.timeout(60)


def test_a_served_msg_without_a_profile_warns_the_remote_client() -> None:
    device = SimProcess("msg", "--listen", "pty", "--time-scale", "20")
    url = re.sub(r"[?&]profile=[^&]*", "", device.url)  # the bare device URL a user would serve
    assert "profile=" not in url
    server = ServeProcess(f"bare={url}", f"named={sim('msg-150')}")
    try:
        with pytest.warns(ProfileAssumed, match="msg-150 assumed"), grippers.open(server.urls["bare"]) as g:
            assert g.info().extra.get("warnings")
        with warnings.catch_warnings():
            warnings.simplefilter("error", ProfileAssumed)  # a named profile: no warning
            with grippers.open(server.urls["named"]) as g:
                assert g.profile.name == "msg-150"
    finally:
        server.close()
        device.close()
