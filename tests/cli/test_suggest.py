"""Issue 16 §6: URL mistakes get the right spelling suggested; sim:// hints never send the user to a
separate command that cannot reach the same simulator."""

from __future__ import annotations

import pytest

from grippers.cli.suggest import bare_forms, suggest

FAMILIES = ["stepfoc", "wsg"]
PROFILES = ["wsg25", "wsg32", "wsg50", "wsg70", "msg-100", "msg-150", "msg-200"]


@pytest.mark.parametrize(
    ("typed", "expected"),
    [
        ("tcp://192.168.1.20", "wsg+tcp://192.168.1.20"),
        ("udp://10.0.0.2:1500", "wsg+udp://10.0.0.2:1500"),
        (
            "serial:///dev/ttyUSB0",
            "wsg+serial:///dev/ttyUSB0 or stepfoc+serial:///dev/ttyUSB0 or robotiq+serial:///dev/ttyUSB0 "
            "or schunk+serial:///dev/ttyUSB0",
        ),
        (
            "/dev/ttyUSB0",  # issue 39 §2: a bare serial port, not "profile file not found"
            "wsg+serial:///dev/ttyUSB0 or stepfoc+serial:///dev/ttyUSB0 or robotiq+serial:///dev/ttyUSB0 "
            "or schunk+serial:///dev/ttyUSB0",
        ),
        ("can://socketcan/can0", "stepfoc+can://socketcan/can0?node=0 or wsg+can://socketcan/can0"),
        ("wsg+tcp:/192.168.1.20", "wsg+tcp://192.168.1.20"),
        ("wsg+tcp:192.168.1.20", "wsg+tcp://192.168.1.20"),
        ("192.168.1.20", "wsg+tcp://192.168.1.20"),
        ("gripper.lab.example:1000", "wsg+tcp://gripper.lab.example:1000"),
        ("wsg5", "wsg50"),
        ("sim://wsg5", "sim://wsg50"),
        ("sim://msg150?time_scale=10", "sim://msg-150?time_scale=10"),
        ("wgs+tcp://h", "wsg+tcp://h"),
        ("stepfoc+cna://socketcan/can0", "stepfoc+can://socketcan/can0"),
    ],
)
def test_suggestions(typed: str, expected: str) -> None:
    # What a bare transport carries is each installed family's to say (its backend's bare_forms).
    assert suggest(typed, FAMILIES, PROFILES, bare_forms()) == expected


@pytest.mark.parametrize("typed", ["wsg+tcp://192.168.1.20", "sim://wsg50", "wsg50", "zzzzzz"])
def test_nothing_to_suggest(typed: str) -> None:
    assert suggest(typed, FAMILIES, PROFILES, bare_forms()) is None


@pytest.mark.parametrize(
    ("argv", "hint"),
    [
        (["state", "tcp://127.0.0.1:9"], "did you mean wsg+tcp://127.0.0.1:9?"),
        (["info", "wsg5"], "did you mean wsg50?"),
        (["state", "sim://wsg5"], "did you mean sim://wsg50?"),
        (["probe", "wsg+tcp:/127.0.0.1"], "did you mean wsg+tcp://127.0.0.1?"),
        (["state", "/dev/ttyUSB0"], "grippers probe serial:///dev/ttyUSB0"),
        (
            ["state", "/dev/ttyUSB0"],
            "did you mean wsg+serial:///dev/ttyUSB0 or stepfoc+serial:///dev/ttyUSB0",
        ),
    ],
)
def test_the_error_line_carries_the_suggestion(cli, argv: list[str], hint: str) -> None:
    r = cli(*argv, "--timeout", "0.3")
    assert r.returncode == 2 and hint in r.one_error_line()


def test_sim_hint_does_not_send_the_user_to_another_process(cli) -> None:
    r = cli("move", "sim://wsg50", "10")
    line = r.one_error_line()
    assert r.returncode == 1 and "--home" in line and "grippers home" not in line
