"""Issue 29 §1: ``robotiq+urcap://HOST[:63352]`` reaches the URCap socket, a scheme the family declares
(``url_protocols``) on top of the one URL grammar; the gripper keeps the URL as typed."""

from __future__ import annotations

import pytest

import grippers
from grippers.backends import get_backend
from grippers.profiles import load_profile
from grippers.settings import Settings


@pytest.fixture
def urcap_sim():  # noqa: ANN201
    profile = load_profile("robotiq-2f85")
    server = get_backend("robotiq").simulator(
        profile, Settings("sim://robotiq-2f85", {"activated": "true"}, {}), "urcap://127.0.0.1:0"
    )
    yield server
    server.close()
    assert server.error is None


def test_the_urcap_scheme_reaches_the_urcap_socket_and_names_the_gripper_as_typed(urcap_sim) -> None:
    url = urcap_sim.url
    assert url.startswith("robotiq+urcap://127.0.0.1:"), url
    with grippers.open(url, profile="robotiq-2f85") as g:
        assert g.url == url and g.name.endswith(url)
        assert type(g.driver).__name__ == "UrcapClient"
        g.move(0.03)
        assert abs(g.state().width - 0.03) < 1e-3


def test_the_same_socket_by_protocol_query_and_a_scheme_no_family_declares() -> None:
    with pytest.raises(grippers.URLError, match="FAMILY\\+TRANSPORT"):
        grippers.open("wsg+urcap://127.0.0.1:1")  # the WSG declares no such protocol
    with pytest.raises(grippers.URLError, match="FAMILY\\+TRANSPORT"):
        grippers.open("robotiq+modbus://127.0.0.1:1")  # not one the Robotiq declares
    with pytest.raises(grippers.URLError, match="protocol"):
        grippers.open("robotiq+urcap://127.0.0.1:1?protocol=rtu")  # the scheme says urcap already


def test_urcap_exchanges_are_wire_lines_at_vv_and_the_current_is_unreported(
    urcap_sim, caplog: pytest.LogCaptureFixture
) -> None:
    """Issue 39 §1: docs/logging.md promises every frame on ``grippers.wire`` for every family; the socket
    offers no current reading, so ``state().current`` is None (unreported), not 0.0."""
    import logging

    with (
        caplog.at_level(logging.DEBUG, logger="grippers.wire"),
        grippers.open(urcap_sim.url, profile="robotiq-2f85") as g,
    ):
        st = g.state()
        g.move(0.04)
    assert st.current is None
    lines = [r.getMessage() for r in caplog.records if r.name == "grippers.wire"]
    assert any(line.endswith("->  urcap    GET ACT") for line in lines), lines[:4]
    assert any(line.endswith("<-  urcap    ack") for line in lines), lines[:4]
    assert any("<-  urcap    POS " in line for line in lines)
    assert all(line.startswith(urcap_sim.url) for line in lines)


def test_a_robotiq_opened_without_a_profile_says_which_model_was_assumed() -> None:
    """Issue 39 §1: a Hand-E on the URCap socket, opened without a profile, was taken for a 2F-85 (85 mm of
    stroke for its 50 mm) without a word; now as the MSG does: a ProfileAssumed warning naming the assumed
    profile, in ``info()`` and in ``state --json``'s warnings, and how to name the model."""
    import json
    import subprocess
    import sys
    import warnings

    profile = load_profile("robotiq-hande")
    server = get_backend("robotiq").simulator(
        profile, Settings("sim://robotiq-hande", {"activated": "true"}, {}), "urcap://127.0.0.1:0"
    )
    try:
        with pytest.warns(grippers.ProfileAssumed, match="robotiq-2f85 assumed"):
            g = grippers.open(server.url)
        with g:
            (warning,) = g.info().extra["warnings"]
            assert "robotiq-2f85 assumed" in warning and "--profile robotiq-hande" in warning
        with warnings.catch_warnings():
            warnings.simplefilter("error", grippers.GripperWarning)
            grippers.open(server.url, profile="robotiq-hande").close()  # named: nothing said
        run = subprocess.run(
            [sys.executable, "-m", "grippers", "state", server.url, "--json"],
            capture_output=True,
            text=True,
            timeout=60,
        )
        assert run.returncode == 0, run.stderr
        assert any("robotiq-2f85 assumed" in w for w in json.loads(run.stdout)["warnings"]), run.stdout
    finally:
        server.close()
