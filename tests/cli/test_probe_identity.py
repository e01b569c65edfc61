"""Issue 40 §4: two families answering on one bare serial port are told apart by identity, not by order.

A second family on Robotiq's register map (a plugin's, here a backend registered for the test that opens the
device through the Robotiq driver, as such a plugin's would) offers its candidate before Robotiq's (order 25
< 30). Before, it claimed the port and a real Robotiq on it was reported as the plugin's. Now both are tried
(they share ``protocol="modbus-rtu"``) and the families' ``probe_identity`` checks decide; the output says
who answered and why one was kept, or reports both when no check can tell.
"""

from __future__ import annotations

import json

import pytest

import grippers
import grippers.backends as registry
from grippers.cli import main
from grippers.cli.schemas import validate
from grippers.kit import CommandHooks, Identity, ProbeCandidate

pytestmark = pytest.mark.timeout(90)


class TwinCommands(CommandHooks):
    """Its command hooks: a candidate on a bare serial port, speaking Modbus RTU, and its identity check."""

    def probe_candidates(self, transport, where, options):
        if transport != "serial":
            return []
        url = f"twin+serial://{where.serial_port}?baudrate=115200"
        return [ProbeCandidate(url, order=25, protocol="modbus-rtu")]

    def probe_identity(self, gripper):
        return self.backend.verdict


class TwinBackend:
    """A family on the Robotiq register map: its devices answer the same Modbus reads."""

    family = "twin"
    profile_model = None
    verdict: Identity | None = None  # what its identity check reads back (set by each test)
    commands = TwinCommands()

    def open(self, url, profile, settings):
        timeout = settings.positive("timeout", 1.0)
        baudrate = settings.int("baudrate", 115200)
        settings.check()
        target = f"robotiq+serial://{url.serial_port}?baudrate={baudrate}&profile=robotiq-2f85"
        return grippers.open(target, timeout=timeout)


@pytest.fixture
def twin(monkeypatch):
    backend = TwinBackend()
    monkeypatch.setitem(registry.BUILTIN_BACKENDS, "twin", "tests.cli.test_probe_identity:TwinBackend")
    monkeypatch.setattr(registry, "_cache", {"twin": backend})
    return backend


def _probe(gripper_sim, capsys, *extra: str) -> tuple[dict, str]:
    url = gripper_sim("robotiq-2f85", transport="pty", activated=True)
    path = url.partition("://")[2].partition("?")[0]
    assert main(["probe", f"serial://{path}", "--timeout", "1", "--json", *extra]) == 0
    doc = json.loads(capsys.readouterr().out)
    validate(doc)  # grippers.probe/2, same_port included
    return doc, path


def test_the_family_whose_check_refuses_the_device_does_not_claim_it(gripper_sim, capsys, twin) -> None:
    twin.verdict = Identity(False, "register 0x0100 holds no TWIN signature")
    doc, path = _probe(gripper_sim, capsys)
    found = [g["url"] for g in doc["grippers"]]
    assert found == [f"robotiq+serial://{path}?baudrate=115200"], doc
    shared = doc["grippers"][0]["same_port"]
    assert shared["answered"] == [f"twin+serial://{path}?baudrate=115200", found[0]]
    assert shared["kept"] == found and "TWIN signature" in shared["why"], shared
    (other,) = [o for o in doc["others"] if o["url"].startswith("twin+")]
    assert "not as its family's device" in other["reason"], other


def test_a_device_no_check_can_tell_is_reported_as_both(gripper_sim, capsys, twin) -> None:
    twin.verdict = Identity(None, "the register map has no model register")
    doc, _path = _probe(gripper_sim, capsys)
    assert sorted(g["url"].partition("+")[0] for g in doc["grippers"]) == ["robotiq", "twin"], doc
    assert all("no identity check told them apart" in g["same_port"]["why"] for g in doc["grippers"])


def test_the_text_says_who_answered_and_why_one_was_kept(gripper_sim, capsys, twin) -> None:
    twin.verdict = Identity(False, "register 0x0100 holds no TWIN signature")
    url = gripper_sim("robotiq-2f85", transport="pty", activated=True)
    path = url.partition("://")[2].partition("?")[0]
    assert main(["probe", f"serial://{path}", "--timeout", "1"]) == 0
    out = capsys.readouterr().out
    assert f"twin+serial://{path}?baudrate=115200, robotiq+serial://{path}" in out, out
    assert "answered; the other families' checks refused it (twin: register 0x0100" in out, out
