"""``grippers.backends.commands_of``: the one place the commands find what a family offers them (issue 40
§2): its backend's ``commands`` (a :class:`~grippers.backends.CommandHooks`), or the defaults, which derive
the probe's candidates and the "did you mean" forms from the family's profile URLs.
"""

from __future__ import annotations

import pytest

from grippers.backends import find_backend
from grippers.kit import CommandHooks, ProbeCandidate, commands_of
from grippers.urls import parse_url


def _bare(url: str):
    return parse_url(url, bare_family="bare")


class Plain:
    """A backend with no ``commands``: every hook is the default."""

    family = "plain"
    profile_model = None


def test_a_backend_without_commands_gets_the_defaults(monkeypatch: pytest.MonkeyPatch) -> None:
    hooks = commands_of(Plain())
    assert type(hooks) is CommandHooks and hooks.family == "plain"
    assert hooks.dissector() is None and hooks.raw_probe("tcp") is None and hooks.factory_address is None
    assert hooks.read_settings(object()) is None and hooks.sim_command() is None
    assert not hooks.reports_stroke and hooks.probe_identity(object()) is None
    # No profile names the family: nothing to derive a candidate from.
    assert hooks.probe_candidates("tcp", _bare("tcp://10.0.0.5"), {}) == []
    assert commands_of(None).family == ""  # an unknown family: the defaults of none


def test_the_default_candidates_come_from_the_family_profile_urls(monkeypatch: pytest.MonkeyPatch) -> None:
    hooks = CommandHooks()
    hooks.bind(Plain())
    monkeypatch.setattr(hooks, "_transports", ("tcp", "can"), raising=False)  # as if its profiles said so
    assert hooks.probe_candidates("tcp", _bare("tcp://10.0.0.5:7"), {}) == [
        ProbeCandidate("plain+tcp://10.0.0.5:7", order=50)
    ]
    assert hooks.probe_candidates("tcp", _bare("tcp://10.0.0.5"), {})[0].url == "plain+tcp://10.0.0.5"
    assert hooks.probe_candidates("serial", _bare("serial:///dev/ttyX"), {}) == []  # no profile on serial
    assert hooks.probe_candidates("can", _bare("can://virtual/x"), {}) == []  # node ids unknown: none
    assert hooks.bare_forms() == {"tcp": (50, "plain+tcp://{rest}")}


def test_a_served_gripper_is_not_local() -> None:
    class Opened:
        url = "zenoh://hand?connect=tcp/127.0.0.1:7447"

    hooks = commands_of(find_backend("wsg"))
    assert not hooks.local(Opened())
    Opened.url = "wsg+tcp://127.0.0.1:1000"
    assert hooks.local(Opened())


def test_commands_that_are_not_command_hooks_are_refused() -> None:
    class Wrong:
        family = "wrong"
        commands = object()

    with pytest.raises(TypeError, match="CommandHooks"):
        commands_of(Wrong())


def test_the_built_in_families_ports_come_from_their_profile_models() -> None:
    """The WSG's factory address, probe ports and serial speed are its profile model's (issue 32 §4)."""
    from grippers.backends.wsg_profile import WsgTransport

    wsg = commands_of(find_backend("wsg"))
    t = WsgTransport()
    assert wsg.factory_address == f"tcp://192.168.1.20:{t.tcp_port}"
    assert [c.url for c in wsg.probe_candidates("udp", _bare("udp://10.0.0.5"), {})] == [
        f"wsg+udp://10.0.0.5:{t.udp_port}"
    ]
    serial = wsg.probe_candidates("serial", _bare("serial:///dev/ttyX"), {})
    assert serial[0].url.endswith(f"?baudrate={t.baudrate}")
