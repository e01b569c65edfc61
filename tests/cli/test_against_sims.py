"""Every command against the simulators in subprocesses: WSG over TCP and CAN, MSG over CAN and a UART pty.

Output is checked against the --json schemas (grippers/cli/schemas.py, via the ``cli_json`` fixture) and the
exit codes of docs/cli.md. The CAN tests use python-can's udp_multicast bus between processes with node ids
and WSG CAN ids of their own (docs/protocols.md §2: multicast groups do not isolate on Linux).
"""

from __future__ import annotations

import pytest

T = "2"  # --timeout for commands against a simulator
WSG_CAN_ID = 0x7E8  # STEPFOC node 15, command 52 (unused): no MSG simulator reacts to it
MSG_NODE_WITH_WSG = 12
MSG_NODE = 13


def bare(url: str) -> str:
    """``wsg+tcp://h:p?x`` -> ``tcp://h:p``: what a user who knows only the address types."""
    scheme, rest = url.split("://", 1)
    return f"{scheme.split('+')[-1]}://{rest.split('?', 1)[0]}"


@pytest.fixture
def wsg_tcp(start_sim) -> str:
    return start_sim("wsg", "--listen", "tcp://127.0.0.1:0", "--part-width", "30").url


def test_probe_finds_the_wsg_on_a_bare_tcp_port(wsg_tcp: str, cli, cli_json) -> None:
    doc = cli_json("probe", bare(wsg_tcp), "--timeout", T)
    (dev,) = doc["grippers"]
    assert dev["family"] == "wsg" and dev["model"] == "WSG 50" and dev["firmware"] == "4.0.1"
    assert dev["location"]["transport"] == "tcp" and dev["location"]["host"] == "127.0.0.1"
    assert dev["limits"]["max_width_mm"] == pytest.approx(110.0)
    assert dev["url"].startswith("wsg+tcp://127.0.0.1:")
    # The table form names the model and shows units.
    r = cli("probe", bare(wsg_tcp), "--timeout", T)
    assert r.returncode == 0 and "WSG 50" in r.stdout and " mm" in r.stdout


def test_everyday_commands_against_the_wsg_over_tcp(wsg_tcp: str, cli, cli_json) -> None:
    assert cli_json("home", wsg_tcp, "--timeout", T)["state"]["referenced"] is True
    doc = cli_json("move", wsg_tcp, "40", "--speed", "50", "--timeout", T)
    assert doc["result"]["width_mm"] == pytest.approx(40.0, abs=0.5)
    state = cli_json("state", wsg_tcp, "--timeout", T)
    assert state["state"]["width_mm"] == pytest.approx(40.0, abs=0.5) and state["state"]["faults"] == []
    info = cli_json("info", wsg_tcp, "--timeout", T)["info"]
    assert info["family"] == "wsg" and info["serial"] and info["limits"]["max_force_n"] == pytest.approx(80)
    grasp = cli_json("grasp", wsg_tcp, "25", "--force", "20", "--speed", "50", "--timeout", T)
    assert grasp["ok"] and grasp["result"]["grasped"] and grasp["result"]["grasp_state"] == "holding"
    assert grasp["result"]["width_mm"] == pytest.approx(30.0, abs=1.0)
    release = cli_json("release", wsg_tcp, "60", "--timeout", T)
    assert release["result"]["width_mm"] == pytest.approx(60.0, abs=0.5)
    cli_json("stop", wsg_tcp, "--timeout", T)
    r = cli("state", wsg_tcp, "--timeout", T)
    assert r.returncode == 0 and "60.00 mm" in r.stdout


def test_fast_stop_refuses_motion_until_acknowledged(wsg_tcp: str, cli, cli_json) -> None:
    cli_json("home", wsg_tcp, "--timeout", T)
    cli_json("stop", wsg_tcp, "--fast", "--timeout", T)
    assert "fast_stop" in cli_json("state", wsg_tcp, "--timeout", T)["state"]["faults"]
    refused = cli("move", wsg_tcp, "50", "--timeout", T)
    assert refused.returncode == 1 and "fast stop" in refused.one_error_line().lower()
    cli_json("ack", wsg_tcp, "--timeout", T)
    assert cli_json("move", wsg_tcp, "50", "--timeout", T)["state"]["faults"] == []


def test_state_watch_writes_json_lines(wsg_tcp: str, cli) -> None:
    r = cli("state", wsg_tcp, "--watch", "--count", "3", "--interval", "0.05", "--json")
    assert r.returncode == 0, r.stderr
    docs = r.json_lines()
    assert len(docs) == 3 and docs[0]["time"] <= docs[2]["time"]


def test_a_grasp_without_a_part_exits_1_with_the_reason(start_sim, cli) -> None:
    url = start_sim("wsg", "--listen", "tcp://127.0.0.1:0").url
    cli("home", url, "--timeout", T)
    r = cli("grasp", url, "40", "--timeout", T, "--json")
    assert r.returncode == 1
    doc = r.json()
    assert doc["ok"] is False and doc["result"]["grasped"] is False and doc["result"]["reason"]
    assert "no part" in r.one_error_line()


def test_values_beyond_the_limits_are_usage_errors(wsg_tcp: str, cli) -> None:
    r = cli("move", wsg_tcp, "500", "--home", "--timeout", T)
    assert r.returncode == 2 and "500 mm is outside" in r.one_error_line()
    r = cli("grasp", wsg_tcp, "20", "--force", "500", "--timeout", T)
    assert r.returncode == 2 and "force" in r.one_error_line()
    # Checked before anything else: an unhomed gripper still gets the usage error, naming the command.
    r = cli("move", "sim://wsg50", "400", "--timeout", T)
    assert r.returncode == 2 and "move: width 400 mm is outside" in r.one_error_line()


def test_firmware_2_simulator(start_sim, cli_json) -> None:
    url = start_sim("wsg", "--listen", "tcp://127.0.0.1:0", "--firmware", "2.2.0", "--profile", "wsg32").url
    info = cli_json("info", url, "--timeout", T)["info"]
    assert info["firmware"] == "2.2.0" and info["model"] == "WSG 32"


@pytest.mark.udp_multicast
def test_bare_can_bus_lists_the_wsg_and_the_msg(start_sim, cli, cli_json, mcast_channel: str) -> None:
    wsg = start_sim(
        "wsg",
        "--listen",
        f"can://udp_multicast/{mcast_channel}?send_id={WSG_CAN_ID:#x}&recv_id={WSG_CAN_ID + 1:#x}",
    ).url
    start_sim("msg", "--listen", f"can://udp_multicast/{mcast_channel}?node={MSG_NODE_WITH_WSG}")
    doc = cli_json(
        "probe", "-i", "udp_multicast", "-c", mcast_channel, "--can-id", hex(WSG_CAN_ID), "--timeout", "0.5"
    )
    found = {d["family"]: d for d in doc["grippers"] if d["location"]["channel"] == mcast_channel}
    msg = [d for d in doc["grippers"] if d["location"]["node"] == MSG_NODE_WITH_WSG]
    assert len(msg) == 1 and msg[0]["family"] == "stepfoc" and msg[0]["model"] == "MSG 150"
    assert found["wsg"]["location"]["transport"] == "can" and found["wsg"]["model"] == "WSG 50"
    # The WSG's own URL (as probe and the simulator print it) drives it over CAN.
    moved = cli_json("move", found["wsg"]["url"], "30", "--home", "--timeout", T)
    assert moved["state"]["width_mm"] == pytest.approx(30.0, abs=0.5)
    assert cli_json("state", wsg, "--timeout", T)["state"]["width_mm"] == pytest.approx(30.0, abs=0.5)


@pytest.mark.udp_multicast
def test_everyday_commands_against_the_msg_over_can(start_sim, cli, cli_json, mcast_channel: str) -> None:
    url = start_sim(
        "msg", "--listen", f"can://udp_multicast/{mcast_channel}?node={MSG_NODE}", "--part-width", "40"
    ).url
    assert url.endswith(f"node={MSG_NODE}")
    before = cli_json("state", url, "--timeout", T)["state"]
    assert before["referenced"] is False and before["force_n"] is None and before["current_a"] is not None
    assert cli_json("home", url, "--timeout", T)["state"]["referenced"] is True
    moved = cli_json("move", url, "60", "--speed", "80", "--timeout", T)
    assert moved["result"]["width_mm"] == pytest.approx(60.0, abs=1.0)
    grasp = cli_json("grasp", url, "40", "--force", "20", "--timeout", T)
    assert grasp["result"]["grasped"] and grasp["result"]["width_mm"] == pytest.approx(40.0, abs=1.5)
    assert grasp["state"]["grasp_state"] == "holding"
    cli_json("release", url, "--timeout", T)
    info = cli_json("info", url, "--profile", "msg-150", "--timeout", T)["info"]
    assert info["family"] == "stepfoc" and info["extra"]["node"] == MSG_NODE
    assert info["firmware"].isdigit() and info["limits"]["max_current_a"] == pytest.approx(1.0)
    r = cli("state", url, "--timeout", T)
    assert r.returncode == 0 and " A" in r.stdout and " mm" in r.stdout


def test_msg_on_a_uart_pty(start_sim, cli, cli_json) -> None:
    url = start_sim("msg", "--listen", "pty", "--part-width", "40").url
    path = url.split("://", 1)[1]
    doc = cli_json("probe", f"serial://{path}", "--timeout", "1")
    (dev,) = doc["grippers"]
    assert dev["family"] == "stepfoc" and dev["location"]["serial_port"] == path
    assert [m["url"].split(":", 1)[0] for m in doc["silent"] + doc["others"]] == ["wsg+serial"]
    cli_json("home", dev["url"], "--timeout", T)
    moved = cli_json("move", url, "70", "--timeout", T)
    assert moved["state"]["width_mm"] == pytest.approx(70.0, abs=1.0)
    grasp = cli_json("grasp", url, "40", "--timeout", T)
    assert grasp["result"]["grasped"] is True


def test_probe_sim_lists_every_shipped_profile(cli, cli_json) -> None:
    profiles = [p["name"] for p in cli_json("profiles", "list")["profiles"]]
    doc = cli_json("probe", "sim://", "--timeout", T, timeout=60)
    assert sorted(d["location"]["profile"] for d in doc["grippers"]) == sorted(profiles)
    assert {d["family"] for d in doc["grippers"]} == {"wsg", "stepfoc", "robotiq", "schunk"}
    assert all(d["url"] == f"sim://{d['profile']}" for d in doc["grippers"])
    r = cli("probe", "sim://", "--timeout", T, timeout=60)
    assert r.returncode == 0 and "WSG 70" in r.stdout and "MSG 200" in r.stdout


def test_commands_on_an_in_process_simulator(cli, cli_json) -> None:
    r = cli("move", "sim://wsg25?time_scale=50", "20")
    assert r.returncode == 1 and "not referenced" in r.one_error_line() and "--home" in r.stderr
    doc = cli_json("move", "sim://wsg25?time_scale=50", "20", "--home")
    assert doc["result"]["width_mm"] == pytest.approx(20.0, abs=0.5)
    doc = cli_json("grasp", "sim://wsg70?time_scale=50&part_width_mm=30", "30", "--home", "--force", "100")
    assert doc["result"]["grasped"] is True and doc["result"]["force_n"] == pytest.approx(100, rel=0.1)
    doc = cli_json("move", "sim://msg-100?time_scale=50", "40", "--home")
    assert doc["state"]["width_mm"] == pytest.approx(40.0, abs=1.0) and doc["state"]["referenced"] is True
