"""Usage errors, help and examples: exit code 2, one line on stderr, every command documented."""

from __future__ import annotations

import pytest

from grippers.cli import SUBCOMMANDS, build_parser

COMMANDS = list(SUBCOMMANDS)


def test_every_command_has_help_with_an_example() -> None:
    parser = build_parser()
    sub = next(a for a in parser._actions if a.dest == "command")
    for name in COMMANDS:
        sp = sub.choices[name]
        text = sp.format_help()
        assert "Example: grippers " in text, name
    from grippers.cli.sim import family_parser

    for family in ("wsg", "msg", "robotiq"):
        assert "Example: grippers sim " + family in family_parser(family)[0].format_help()


def test_the_can_flags_are_python_cans() -> None:
    text = build_parser()._subparsers._group_actions[0].choices["probe"].format_help()
    for flag in ("-i INTERFACE", "-c CHANNEL", "-b BITRATE"):
        assert flag in text


@pytest.mark.parametrize(
    "argv",
    [
        ["probe", "foo://nowhere"],
        ["probe", "tcp://"],
        ["probe", "tcp://127.0.0.1:notaport"],
        ["probe", "can://socketcan"],
        ["probe", "just-words"],
        ["move", "wsg+tcp://127.0.0.1:1", "abc"],
        ["move", "wsg+tcp://127.0.0.1:1", "-5"],
        ["grasp", "wsg+tcp://127.0.0.1:1", "--force", "0"],
        ["state", "wsg+tcp://127.0.0.1:1", "--timeout", "nan"],
        ["state", "foo+tcp://127.0.0.1:1"],
        ["state", "wsg+smoke://127.0.0.1:1"],
        ["state", "no-such-profile"],
        ["state", "sim://wsg50?no_such_setting=1"],
        ["info", "sim://no-such-profile"],
        ["monitor"],
        ["monitor", "--proxy", "127.0.0.1:0"],
        ["profiles", "show"],
        ["sim", "wsg", "--listen", "gopher://x"],
        ["nosuchcommand"],
    ],
)
def test_usage_errors_exit_2_with_one_line(argv: list[str], cli) -> None:
    r = cli(*argv, timeout=20)
    assert r.returncode == 2, (r.stdout, r.stderr)
    assert "error" in r.one_error_line()


def test_debug_shows_the_traceback(cli) -> None:
    r = cli("--debug", "state", "no-such-profile", timeout=20)
    assert r.returncode != 0 and "Traceback" in r.stderr and "ProfileError" in r.stderr


def test_python_dash_m_without_command_prints_help_and_exits_2(cli) -> None:
    r = cli(timeout=20)
    assert r.returncode == 2
    assert "COMMAND" in r.stdout


def test_help_lists_commands(cli) -> None:
    r = cli("--help", timeout=20)
    assert r.returncode == 0
    for name in COMMANDS:
        assert name in r.stdout
