"""Issue 22 §3: the library logs under ``grippers.*``; every frame or packet on the wire at DEBUG under one
logger, ``grippers.wire``, in the decoded form ``grippers monitor`` prints; ``-v``/``-q``/``--log-level`` on
the command line."""

from __future__ import annotations

import logging

import pytest

import grippers


def _wire_lines(caplog: pytest.LogCaptureFixture) -> list[str]:
    return [r.getMessage() for r in caplog.records if r.name == "grippers.wire"]


@pytest.mark.parametrize(
    ("url", "request_text", "reply_text"),
    [
        (
            "sim://wsg50",
            "->  wsg      GET_SYSTEM_STATE (40h)",
            "<-  wsg      GET_SYSTEM_STATE (40h) E_SUCCESS",
        ),
        (
            "sim://msg-150",
            "->  stepfoc  07A  node 0 gripper_command poll",
            "<-  stepfoc  078  node 0 gripper_status",
        ),
        ("sim://msg-150?transport=pty", "->  stepfoc  #Gripinfo", "<-  stepfoc  I am a gripper"),
    ],
)
def test_every_frame_on_the_wire_is_logged_decoded(
    caplog: pytest.LogCaptureFixture, url: str, request_text: str, reply_text: str
) -> None:
    with caplog.at_level(logging.DEBUG, logger="grippers.wire"), grippers.open(url) as g:
        g.state()
    lines = _wire_lines(caplog)
    assert any(request_text in line for line in lines), lines[:5]
    assert any(reply_text in line for line in lines), lines[:5]


def test_nothing_is_logged_on_the_wire_unless_asked(caplog: pytest.LogCaptureFixture) -> None:
    with caplog.at_level(logging.INFO, logger="grippers"), grippers.open("sim://wsg50") as g:
        g.state()
    assert _wire_lines(caplog) == []
    assert any(
        "opened (profile wsg50)" in r.getMessage() for r in caplog.records if r.levelno == logging.INFO
    )


def test_cli_verbosity_flags(cli) -> None:
    quiet = cli("state", "sim://wsg50", "-q")
    assert quiet.returncode == 0 and quiet.stderr == ""
    info = cli("state", "sim://wsg50", "-v")
    assert " INFO grippers.api: " in info.stderr and "grippers.wire" not in info.stderr
    debug = cli("-vv", "state", "sim://wsg50")
    assert " DEBUG grippers.wire: " in debug.stderr and "GET_SYSTEM_STATE (40h)" in debug.stderr
    named = cli("state", "sim://wsg50", "--log-level", "debug")
    assert " DEBUG grippers.wire: " in named.stderr
    assert "width:" in debug.stdout and "DEBUG" not in debug.stdout


def test_faults_are_logged_at_info_when_they_change(caplog: pytest.LogCaptureFixture) -> None:
    with caplog.at_level(logging.INFO, logger="grippers"), grippers.open("sim://wsg50") as g:
        g.state()
        g.fast_stop()
        g.state()
        g.state()  # unchanged: no second line
        g.acknowledge()
        g.state()
    lines = [r.getMessage() for r in caplog.records if "faults:" in r.getMessage()]
    assert len(lines) == 2 and lines[0].endswith("faults: fast_stop") and lines[1].endswith("faults: none")
