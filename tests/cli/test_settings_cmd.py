"""Issue 16 §5: device settings on the command line, against the simulators over real transports."""

from __future__ import annotations

import json
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
