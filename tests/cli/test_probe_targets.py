"""What probe tries for a target: pure expansion rules, no devices."""

from __future__ import annotations

import pytest

from grippers.cli.output import UsageError
from grippers.cli.probe_targets import expand, is_loopback, location_of, machine_targets


def test_bare_tcp_defaults_to_the_wsg_port() -> None:
    plan = expand("tcp://127.0.0.1")
    assert [c.url for c in plan.candidates] == ["wsg+tcp://127.0.0.1:1000"]
    assert plan.candidates[0].location["port"] == 1000


def test_bare_serial_tries_every_family_one_after_another() -> None:
    plan = expand("/dev/ttyUSB0")
    urls = [c.url for c in plan.candidates]
    assert urls == [  # each family's backend offers its own (probe_candidates), in the order they declare
        "wsg+serial:///dev/ttyUSB0?baudrate=115200",
        "stepfoc+serial:///dev/ttyUSB0?baudrate=256000",
        "robotiq+serial:///dev/ttyUSB0?baudrate=115200",
        "schunk+serial:///dev/ttyUSB0",
    ]
    assert len({c.group for c in plan.candidates}) == 1
    assert plan.candidates[0].location["serial_port"] == "/dev/ttyUSB0"


def test_bare_can_tries_sixteen_nodes_and_the_wsg_ids() -> None:
    plan = expand("can://udp_multicast/239.74.163.1", options={"can_ids": [0x000, 0x7E8]})
    nodes = [c.location["node"] for c in plan.candidates if c.url.startswith("stepfoc")]
    assert nodes == list(range(16))
    wsg = [c for c in plan.candidates if c.url.startswith("wsg+can")]
    assert [c.url.split("?")[1] for c in wsg] == [
        "send_id=0x000&recv_id=0x001",
        "send_id=0x7E8&recv_id=0x7E9",
    ]
    # A WSG packet on 0x000 would be node 0's E-stop frame: it waits until node 0 is known to be absent.
    assert wsg[0].unless_nodes == (0,) and wsg[1].unless_nodes == (15,)
    assert plan.candidates[3].location["channel"] == "239.74.163.1"


def test_family_urls_and_sim() -> None:
    assert expand("wsg+tcp://127.0.0.1:5000").candidates[0].location["port"] == 5000
    assert expand("sim://").sim_all
    assert expand("sim://wsg50").candidates[0].location["profile"] == "wsg50"
    assert location_of("stepfoc+can://virtual/ch?node=3")["node"] == 3


@pytest.mark.parametrize("bad", ["ftp://x", "tcp://", "tcp://h:99999", "can://iface", "serial://", "words"])
def test_malformed_targets_are_usage_errors(bad: str) -> None:
    with pytest.raises(UsageError):
        expand(bad)


def test_machine_scan_includes_the_wsg_factory_address_unless_told_not_to() -> None:
    assert "wsg+tcp://192.168.1.20:1000" in [c.url for c in machine_targets(network=True).candidates]
    plan = machine_targets(network=False)
    assert not any(c.url.startswith("wsg+tcp") for c in plan.candidates)
    assert any("192.168.1.20" in s["target"] and "--no-network" in s["reason"] for s in plan.skipped)


def test_loopback() -> None:
    assert is_loopback("127.0.0.1") and is_loopback("::1") and is_loopback("localhost")
    assert not is_loopback("192.168.1.20")
