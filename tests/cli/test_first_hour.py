"""Issue 22 §1-§2: no silent assumption, and commands that behave alike (a new user's first hour).

Each test runs the real CLI (a subprocess) or the real API against a simulator over a real transport.
"""

from __future__ import annotations

import argparse
import json
import os
import shutil
import socket
import subprocess
import sys
import warnings
from importlib import metadata
from pathlib import Path

import pytest

import grippers
from grippers.cli import SUBCOMMANDS, build_parser
from grippers.cli.monitor import apply_url
from grippers.cli.schemas import validate

from .conftest import monitor_proxy

ROOT = Path(__file__).resolve().parents[2]
GLASS = """
name = "wsg50-glass"
extends = "wsg50"
description = "WSG 50 for glass parts: 15 N at most"
[safety]
max_force_n = 15
"""


@pytest.fixture
def msg_pty_url(gripper_sim):
    """A simulated MSG 150 on a pseudo-terminal; the URL opens it WITHOUT naming a profile. No client holds
    the port meanwhile: serial ports open exclusively (drivers/serial_ports.py)."""
    return str(gripper_sim("msg-150", transport="serial")).split("?")[0]  # without its profile=


@pytest.fixture
def wsg_tcp_url():
    with grippers.open("sim://wsg50") as g:
        yield g.simulator.url


# --- §1 never a silent assumption ----------------------------------------------------------------------


def test_python_open_of_an_msg_without_profile_warns(msg_pty_url: str) -> None:
    with pytest.warns(grippers.ProfileAssumed, match="msg-150 assumed"):
        g = grippers.open(msg_pty_url)
    g.close()
    with warnings.catch_warnings():
        warnings.simplefilter("error", grippers.GripperWarning)
        grippers.open(msg_pty_url, profile="msg-150").close()  # named: nothing assumed, nothing said


def test_every_cli_command_says_the_msg_model_was_assumed(cli, msg_pty_url: str) -> None:
    r = cli("state", msg_pty_url, "--json")
    assert r.returncode == 0, r.stderr
    assert r.stderr.strip().startswith("grippers state: warning: ") and "msg-150 assumed" in r.stderr
    assert any("msg-150 assumed" in w for w in r.json()["warnings"])
    r = cli("info", msg_pty_url, "--json")
    assert "grippers info: warning:" in r.stderr and r.json()["warnings"]
    r = cli("stop", msg_pty_url, "--json")
    assert "grippers stop: warning:" in r.stderr and r.json()["warnings"]
    quiet = cli("state", msg_pty_url, "--json", "--profile", "msg-150")
    assert quiet.returncode == 0 and quiet.stderr == "" and quiet.json()["warnings"] == []


def test_msg_firmware_is_one_value_in_api_cli_and_json(cli, msg_pty_url: str) -> None:
    with grippers.open(msg_pty_url, profile="msg-150") as g:
        firmware = g.info().firmware
    doc = cli("info", msg_pty_url, "--profile", "msg-150", "--json").json()
    assert doc["info"]["firmware"] == firmware
    text = cli("info", msg_pty_url, "--profile", "msg-150").stdout
    assert "firmware:" in text and text.split("firmware:")[1].split()[0] == firmware


def test_a_variant_on_the_search_path_is_never_taken_for_a_plain_open(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch, wsg_tcp_url: str, cli
) -> None:
    (tmp_path / "wsg50-glass.toml").write_text(GLASS)
    monkeypatch.setenv("GRIPPERS_PROFILE_PATH", str(tmp_path))
    with grippers.open(wsg_tcp_url) as g:
        assert g.profile.name == "wsg50" and g.limits.max_force > 15
    with grippers.open(wsg_tcp_url, profile="wsg50-glass") as g:  # named: the variant it is
        assert g.profile.name == "wsg50-glass" and g.limits.max_force == 15
    env = {**os.environ, "GRIPPERS_PROFILE_PATH": str(tmp_path)}
    probe = subprocess.run(
        [sys.executable, "-m", "grippers", "probe", wsg_tcp_url, "--json"],
        cwd=ROOT,
        env=env,
        capture_output=True,
        text=True,
        timeout=60,
    )
    assert '"profile": "wsg50"' in probe.stdout, probe.stdout + probe.stderr


def test_a_user_file_named_like_the_builtin_still_replaces_it(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch, wsg_tcp_url: str
) -> None:
    (tmp_path / "wsg50.toml").write_text(GLASS.replace('name = "wsg50-glass"', 'name = "wsg50"'))
    monkeypatch.setenv("GRIPPERS_PROFILE_PATH", str(tmp_path))
    with grippers.open(wsg_tcp_url) as g:  # a deliberate correction of the stock profile is used
        assert g.limits.max_force == 15


# --- §2 commands that behave alike ----------------------------------------------------------------------


def test_a_typo_names_the_command_and_its_help(cli) -> None:
    r = cli("grasp", "sim://", "10", "--forse", "3")
    assert r.returncode == 2
    line = r.one_error_line()
    assert line.startswith("grippers grasp: error: unrecognized --forse")
    assert "did you mean --force?" in line and "see grippers grasp --help" in line


def test_a_missing_profile_file_says_file_not_found(cli) -> None:
    r = cli("info", "nope.toml")
    assert r.returncode == 2
    line = r.one_error_line()
    assert "profile file not found" in line and "did you mean" not in line


def test_help_lists_every_exit_code(cli) -> None:
    text = cli("--help").stdout
    assert "130" in text and "interrupted" in text
    assert "130" in cli("state", "--help").stdout


def test_every_command_takes_the_log_flags() -> None:
    parser = build_parser()
    subparsers = next(a for a in parser._actions if isinstance(a, argparse._SubParsersAction)).choices
    for name in SUBCOMMANDS:
        options = {o for action in subparsers[name]._actions for o in action.option_strings}
        assert {"-v", "--verbose", "-q", "--quiet", "--log-level"} <= options, name
    args, _ = parser.parse_known_args(["-v", "state", "sim://"])
    assert args.verbose == 1  # given before the command's name, not reset by the subcommand's default


def test_state_watch_takes_rate_like_record_and_serve(cli) -> None:
    r = cli("state", "sim://wsg50", "--watch", "--count", "2", "--rate", "20", "--json")
    assert r.returncode == 0, r.stderr
    assert len(r.json_lines()) == 2


def test_dir_lists_the_lazy_api() -> None:
    names = dir(grippers)
    for name in ("open", "Gripper", "GraspState", "load_profile", "MotionHandle", "ProfileAssumed"):
        assert name in names
    assert set(grippers.__all__) <= set(names)


def test_the_version_has_one_source(cli) -> None:
    assert metadata.version("grippers") == grippers.__version__
    assert cli("--version").stdout.strip() == f"grippers {grippers.__version__}"
    text = (ROOT / "pyproject.toml").read_text()
    assert 'dynamic = ["version"]' in text and "\nversion =" not in text.split("[project]")[1].split("\n[")[0]


# --- grippers sim: the device's port, or a working one ---------------------------------------------------


def _sim(*args: str, prefix: tuple[str, ...] = ()) -> subprocess.Popen[str]:
    return subprocess.Popen(
        [*prefix, sys.executable, "-m", "grippers", "sim", *args],
        cwd=ROOT,
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,
        text=True,
        env={**os.environ, "PYTHONUNBUFFERED": "1"},
    )


def _first_line(proc: subprocess.Popen[str]) -> str:
    assert proc.stdout is not None
    try:
        return proc.stdout.readline()
    finally:
        proc.terminate()
        proc.wait(timeout=30)


SETPRIV = shutil.which("setpriv")


@pytest.mark.skipif(SETPRIV is None, reason="setpriv (util-linux) drops the right to bind ports below 1024")
def test_sim_without_the_right_to_port_1000_serves_on_a_free_port() -> None:
    # root without CAP_NET_BIND_SERVICE is refused port 1000 exactly as an ordinary user is
    proc = _sim("wsg", "--json", prefix=(str(SETPRIV), "--bounding-set=-net_bind_service"))
    try:
        assert proc.stdout is not None and proc.stderr is not None
        doc = json.loads(proc.stdout.readline())
        assert doc["schema"] == "grippers.sim/1" and not doc["urls"][0].endswith(":1000")
        with grippers.open(doc["urls"][0]) as g:  # and it works
            assert g.info().model == "WSG 50"
    finally:
        proc.terminate()
        proc.wait(timeout=30)
    stderr = proc.stderr.read()
    assert stderr.count("\n") == 1 and "needs root" in stderr and "--listen tcp://127.0.0.1:0" in stderr


def test_sim_on_a_port_in_use_says_so_with_the_fix(cli) -> None:
    with socket.socket() as busy:
        busy.bind(("127.0.0.1", 0))
        busy.listen()
        port = busy.getsockname()[1]
        r = cli("sim", "wsg", "--listen", f"tcp://127.0.0.1:{port}")
    assert r.returncode == 1
    line = r.one_error_line()
    assert "port is in use" in line and "--listen tcp://127.0.0.1:0" in line


def test_sim_prints_its_urls_as_json() -> None:
    proc = _sim("msg", "--json")
    doc = json.loads(_first_line(proc))
    assert doc["schema"] == "grippers.sim/1" and doc["urls"][0].startswith("stepfoc+serial://")
    validate(doc)


# --- monitor takes the URLs every other command takes ---------------------------------------------------


def _monitor_args(*argv: str) -> argparse.Namespace:
    args, _ = build_parser().parse_known_args(["monitor", *argv])
    apply_url(args)
    return args


def test_monitor_reads_can_urls_like_the_other_commands() -> None:
    a = _monitor_args("can://socketcan/can0")
    assert (a.interface, a.channel, a.protocol, a.capture) == ("socketcan", "can0", "auto", None)
    a = _monitor_args("stepfoc+can://socketcan/vcan1?node=3&bitrate=500000")
    assert (a.interface, a.channel, a.protocol, a.bitrate) == ("socketcan", "vcan1", "stepfoc", 500000)
    a = _monitor_args("wsg+can://socketcan/can0?send_id=0x7E8")
    assert (a.protocol, a.can_id) == ("wsg", 0x7E8)
    a = _monitor_args("-c", "can1", "can://socketcan/can0")  # a flag beside the URL wins, as in open()
    assert a.channel == "can1"
    a = _monitor_args("wsg+tcp://192.168.1.20")
    assert a.to == ("192.168.1.20", 1000) and a.proxy == ("127.0.0.1", 0)


def test_monitor_of_a_serial_url_is_a_usage_error(cli) -> None:
    r = cli("monitor", "wsg+serial:///dev/ttyUSB0")
    assert r.returncode == 2 and "monitor watches a CAN bus" in r.one_error_line()


def test_monitor_of_a_wsg_tcp_url_relays_and_decodes(wsg_tcp_url: str) -> None:
    with (
        monitor_proxy(wsg_tcp_url, "--json", stop_timeout=30) as proxy,
        grippers.open(f"wsg+tcp://127.0.0.1:{proxy.port}") as g,
    ):
        g.home()
    commands = {json.loads(x)["command"] for x in proxy.out.splitlines()}
    assert "HOMING (20h)" in commands
