"""Issue 16 §5: device settings on the command line, against the simulators over real transports."""

from __future__ import annotations

import json
import os
import re
import select
import subprocess
import sys
import time

import pytest

from grippers.backends import get_backend
from grippers.cli import main
from grippers.cli.schemas import validate
from grippers.profiles import load_profile
from grippers.settings import Settings


def test_wsg_settings_read_and_change(cli, sim_process) -> None:
    url = sim_process("wsg", "--listen", "tcp://127.0.0.1:0").url
    before = cli("settings", url, "--json").json()
    assert before["family"] == "wsg" and before["changed"] == []
    s = before["settings"]
    assert s["soft_limits"] == {"unavailable": "not set"} and s["device_tag"] == {"unavailable": "not set"}
    assert isinstance(s["temperature_c"], float) and s["finger_1"]["type"]
    r = cli(
        "settings",
        url,
        "--soft-limits",
        "10",
        "90",
        "--tag",
        "bench-2",
        "--acceleration",
        "500",
        "--force-limit",
        "40",
        "--json",
    )
    after = r.json()
    assert after["changed"] == ["soft_limits", "device_tag", "acceleration_mm_s2", "force_limit_n"]
    assert after["settings"]["soft_limits"] == {"min_mm": 10.0, "max_mm": 90.0}
    assert after["settings"]["device_tag"] == "bench-2"
    assert after["settings"]["acceleration_mm_s2"] == 500.0 and after["settings"]["force_limit_n"] == 40.0
    text = cli("settings", url).stdout
    assert "soft limits:  10.0 .. 90.0 mm" in text and "device tag:   bench-2" in text
    cleared = cli("settings", url, "--clear-soft-limits", "--json").json()
    assert cleared["settings"]["soft_limits"] == {"unavailable": "not set"}


def test_wsg_settings_out_of_range_is_a_usage_error(cli, sim_process) -> None:
    url = sim_process("wsg", "--listen", "tcp://127.0.0.1:0").url
    r = cli("settings", url, "--soft-limits", "10", "500")
    assert r.returncode == 2 and "500" in r.one_error_line()
    assert cli("settings", url, "--node-id", "3").returncode == 2


def test_wsg_2x_has_no_finger_commands(cli, sim_process) -> None:
    url = sim_process("wsg", "--listen", "tcp://127.0.0.1:0", "--firmware", "2.2.0").url
    doc = cli("settings", url, "--json").json()
    assert "unavailable" in doc["settings"]["finger_1"]


@pytest.fixture
def msg_on_virtual_bus():
    channel = f"settings-{time.monotonic_ns()}"
    profile = load_profile("msg-150")
    backend = get_backend("stepfoc")
    model = backend.sim_model(profile, 0, None)
    server = backend.serve([model], f"can://virtual/{channel}", Settings("sim://msg-150", {}, {}))
    yield model, f"stepfoc+can://virtual/{channel}?node=0"
    server.close()


def test_msg_node_id_asks_first(msg_on_virtual_bus, capsys) -> None:
    model, url = msg_on_virtual_bus
    assert main(["settings", url, "--node-id", "5"]) == 2  # stdin is not a terminal: no silent change
    assert "--yes" in capsys.readouterr().err
    assert model.node == 0 and model.saved_node == 0


def test_msg_node_id_change_and_save(msg_on_virtual_bus, capsys) -> None:
    model, url = msg_on_virtual_bus
    assert main(["settings", url, "--node-id", "5", "--yes", "--json"]) == 0
    doc = json.loads(capsys.readouterr().out)
    validate(doc)
    assert doc["changed"] == ["node_id"] and doc["settings"]["node_id"] == 5
    assert doc["url"].endswith("?node=5")
    assert model.node == 5 and model.saved_node == 5  # saved to the driver's flash (command 13)
    assert main(["settings", doc["url"], "--json"]) == 0
    assert json.loads(capsys.readouterr().out)["settings"]["node_id"] == 5


# --- issue 19 §2 and issue 23: nothing changes before every check passed --------------------------------


@pytest.fixture
def two_msgs_on_virtual_bus():
    """Two MSG nodes (0 and 3) on one python-can virtual bus: ids a bench with two grippers uses."""
    channel = f"settings-two-{time.monotonic_ns()}"
    profile = load_profile("msg-150")
    backend = get_backend("stepfoc")
    models = [backend.sim_model(profile, node, None) for node in (0, 3)]
    server = backend.serve(models, f"can://virtual/{channel}", Settings("sim://msg-150", {}, {}))
    yield models, f"stepfoc+can://virtual/{channel}"
    server.close()


def test_msg_node_id_taken_by_another_node_is_refused(two_msgs_on_virtual_bus, capsys) -> None:
    (first, second), base = two_msgs_on_virtual_bus
    assert main(["settings", f"{base}?node=0", "--node-id", "3", "--yes"]) == 2
    err = capsys.readouterr().err
    assert "already answers as node 3" in err and "nothing changed" in err
    assert first.node == 0 and first.saved_node == 0  # neither changed nor saved
    assert second.node == 3
    # a free id still works
    assert main(["settings", f"{base}?node=0", "--node-id", "4", "--yes", "--json"]) == 0
    assert first.node == 4 and first.saved_node == 4


def test_msg_save_with_a_watchdog_says_what_power_up_will_do(msg_on_virtual_bus, capsys) -> None:
    model, url = msg_on_virtual_bus
    # no terminal, no --yes: the note is shown, nothing is sent
    assert main(["settings", url, "--watchdog", "500", "--save"]) == 2
    err = capsys.readouterr().err
    assert "after every power-up the node raises 'timeout'" in err and "--watchdog 0 --save" in err
    assert model.watchdog.timeout_ms == 0
    assert (
        main(["settings", url, "--watchdog", "500", "--heartbeat", "200", "--save", "--yes", "--json"]) == 0
    )
    captured = capsys.readouterr()
    assert "--heartbeat 0 --save" in captured.err
    doc = json.loads(captured.out)
    assert doc["changed"] == ["watchdog_ms", "heartbeat_ms"]
    assert model.watchdog.timeout_ms == 500 and model.heartbeat_ms == 200


def test_msg_save_alone_warns_that_unknown_periods_are_saved_too(msg_on_virtual_bus, capsys) -> None:
    model, url = msg_on_virtual_bus
    assert main(["settings", url, "--save", "--yes"]) == 0
    err = capsys.readouterr().err
    assert "cannot report its watchdog and heartbeat period" in err
    assert "--watchdog 0 --heartbeat 0" in err


def test_msg_watchdog_out_of_range_is_refused_before_sending(msg_on_virtual_bus, capsys) -> None:
    model, url = msg_on_virtual_bus
    with pytest.raises(SystemExit) as exited:  # refused while the arguments are parsed (issue 33 §3)
        main(["settings", url, "--watchdog", str(2**32), "--yes"])
    assert exited.value.code == 2
    assert "--watchdog" in capsys.readouterr().err
    assert model.watchdog.timeout_ms == 0


def test_wsg_absurd_acceleration_is_refused_before_anything_is_written(cli, sim_process) -> None:
    url = sim_process("wsg", "--listen", "tcp://127.0.0.1:0").url
    r = cli("settings", url, "--tag", "must-not-land", "--acceleration", "1e9")
    assert r.returncode == 2 and "acceleration" in r.one_error_line() and "5000" in r.one_error_line()
    after = cli("settings", url, "--json").json()["settings"]
    assert after["device_tag"] == {"unavailable": "not set"}  # the tag before it was not written either
    assert after["acceleration_mm_s2"] != 1e9


def _serve(*args: str) -> tuple[subprocess.Popen[str], str]:
    """``grippers serve ARGS`` on a loopback port chosen at run time; returns the process and its URL."""
    proc = subprocess.Popen(
        [sys.executable, "-m", "grippers", "serve", *args, "--listen", "tcp/127.0.0.1:0"],
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,
        text=True,
        env={**os.environ, "PYTHONUNBUFFERED": "1"},
    )
    assert proc.stdout is not None
    fd, seen, deadline = proc.stdout.fileno(), "", time.monotonic() + 30
    while time.monotonic() < deadline:
        if select.select([fd], [], [], 0.2)[0]:
            chunk = os.read(fd, 65536).decode()
            seen += chunk
            m = re.search(r"^\S+: .* serving at (\S+)$", seen, re.M)
            if m:
                return proc, m.group(1)
            if not chunk:
                break
    proc.kill()
    raise AssertionError(f"grippers serve printed {seen!r}")


def test_settings_over_zenoh_refuses_before_changing_anything(cli, sim_process) -> None:
    pytest.importorskip("zenoh")
    device = sim_process("wsg", "--listen", "tcp://127.0.0.1:0").url
    proc, url = _serve(device)
    try:
        r = cli("settings", url, "--tag", "over-the-network", "--acceleration", "500")
        assert r.returncode == 2 and "not served over the network" in r.one_error_line()
    finally:
        proc.terminate()
        proc.communicate(timeout=15)
    assert cli("settings", device, "--json").json()["settings"]["device_tag"] == {"unavailable": "not set"}


def test_settings_without_options_shows_what_the_readme_says(capsys) -> None:
    # Issue 33 §3: the README said `settings` shows an MSG's watchdog and heartbeat; the node cannot report
    # either, and the command shows its node id, temperature and supply voltage. Each family's line of the
    # README's paragraph names exactly what the command prints.
    from pathlib import Path

    readme = (Path(__file__).resolve().parents[2] / "README.md").read_text(encoding="utf-8")
    paragraph = readme[readme.index("`grippers settings URL` shows") :].split("\n\n", 1)[0]
    paragraph = " ".join(paragraph.split())
    wsg_part = paragraph[paragraph.index("on a WSG") : paragraph.index("; on an MSG")]
    msg_part = paragraph[paragraph.index("on an MSG") : paragraph.index(", and over CAN")]
    named = {
        "temperature": "temperature",
        "acceleration": "acceleration",
        "force limit": "force limit",
        "soft limits": "soft limits",
        "device tag": "device tag",
        "finger 1": "fingers",
        "finger 2": "fingers",
        "node id": "node id",
        "supply": "supply voltage",
    }
    for url, part in (("sim://wsg50", wsg_part), ("sim://msg-150", msg_part)):
        assert main(["settings", url]) == 0
        labels = [line.split(":", 1)[0].strip() for line in capsys.readouterr().out.splitlines()]
        assert labels and all(named[label] in part for label in labels), (labels, part)
        assert sum(part.count(word) for word in set(named.values())) == len(set(named[x] for x in labels))
    assert "watchdog" not in msg_part and "heartbeat" not in msg_part


def test_a_period_out_of_range_is_a_usage_error_with_the_numbers_as_written(capsys) -> None:
    # Was "heartbeat 4.29497e+09 is above 4.29497e+09", after the gripper had been opened.
    with pytest.raises(SystemExit) as exited:  # refused while parsing, before anything opens
        main(["settings", "sim://msg-150", "--heartbeat", "4294967296"])
    assert exited.value.code == 2
    err = capsys.readouterr().err
    assert "--heartbeat: period 4294967296 is above 4294967295 (allowed: 0..4294967295)" in err, err
    assert "e+09" not in err and len(err.strip().splitlines()) == 1
