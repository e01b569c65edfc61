"""A family's ``selftest_checks`` run whether or not it offers device settings (issue 40: a plugin had to
add a read-only settings hook only to get its own self-test lines).

The Robotiq offers no device settings; its command hooks (``commands``, docs/backends.md "Hooks the commands
call") are given a ``selftest_checks`` for the test, and the run must carry its line beside the "offers no
device settings" one.
"""

from __future__ import annotations

import json

import pytest

from grippers.backends import find_backend
from grippers.backends.command_hooks import commands_of
from grippers.cli import main

from ..selftest_verdicts import assert_passes_but_timed_speeds

pytestmark = pytest.mark.timeout(90)


def test_a_family_without_settings_still_gets_its_selftest_lines(monkeypatch, capsys) -> None:
    seen = []

    def selftest_checks(gripper, add):
        seen.append(gripper.info().family)
        add("family check", "ok", "ok", "PASS", "from the family's hook")

    monkeypatch.setattr(commands_of(find_backend("robotiq")), "selftest_checks", selftest_checks)
    code = main(["selftest", "sim://robotiq-2f85?time_scale=5&activated=true", "--yes", "--json"])
    out = capsys.readouterr().out
    assert code in (0, 3), out
    lines = assert_passes_but_timed_speeds(json.loads(out))
    assert lines["settings"]["note"] == "the robotiq backend offers no device settings", lines["settings"]
    assert seen == ["robotiq"]
    assert lines["family check"] == {
        **lines["family check"],
        "verdict": "PASS",
        "note": "from the family's hook",
    }
