"""Issue 33 §3: ``grippers probe`` and ``grippers monitor`` honour ``?port=`` of a ``udp_multicast`` bus.

python-can's udp_multicast bus is one UDP port for every group on Linux, so a bus of one's own is a port of
one's own (tests/mcast.py). The probe built its candidate URLs without the URL's query and the monitor opened
the bus without it: both watched python-can's default port, where they found another process's nodes.
The simulator here listens on a private port only, so reaching its node proves the port was used.
"""

from __future__ import annotations

import json
import os
import signal
import subprocess
import sys
import threading
import time
from collections.abc import Callable, Iterator
from pathlib import Path
from typing import Any

import can
import pytest

import grippers
from grippers.cli.output import UsageError
from grippers.cli.probe_targets import expand
from grippers.drivers.stepfoc.sim import MsgModel, serve_can
from grippers.urls import parse_url

from ..mcast import private_port

ROOT = Path(__file__).resolve().parents[2]
GROUP = "239.74.201.7"
NODE = 13  # test_against_sims has a node 13 on the default port: only the private port tells them apart


def test_every_probe_candidate_carries_the_bus_options() -> None:
    plan = expand(f"can://udp_multicast/{GROUP}?port=45123")
    assert len(plan.candidates) == 16 + 1  # the STEPFOC nodes and the WSG's CAN ids
    for candidate in plan.candidates:
        assert parse_url(candidate.url).params["port"] == "45123", candidate.url
    socketcan = expand("can://socketcan/can0?bitrate=500000")
    assert all(parse_url(c.url).params["bitrate"] == "500000" for c in socketcan.candidates)
    assert all("port" not in parse_url(c.url).params for c in socketcan.candidates)


def test_a_misspelt_bus_option_of_a_probe_target_is_refused() -> None:
    with pytest.raises(UsageError, match="unknown parameter.*prot.*did you mean port"):
        expand(f"can://udp_multicast/{GROUP}?prot=45123")


@pytest.fixture
def private_bus() -> Iterator[str]:
    pytest.importorskip("msgpack", reason="python-can's udp_multicast interface needs msgpack")
    port = private_port()
    try:
        server = serve_can([MsgModel(node=NODE)], f"can://udp_multicast/{GROUP}?port={port}", time_scale=50.0)
    except grippers.ConnectionLost as exc:
        pytest.skip(f"python-can udp_multicast unavailable here: {exc}")
    try:
        yield f"can://udp_multicast/{GROUP}?port={port}"
    finally:
        server.close()


@pytest.mark.udp_multicast
def test_probe_searches_the_urls_port(private_bus: str, cli: Callable[..., Any]) -> None:
    result = cli("probe", private_bus, "--timeout", "1", "--json", timeout=120)
    assert result.returncode == 0, result.stderr
    found = [d for d in json.loads(result.stdout)["grippers"] if d["location"]["node"] == NODE]
    assert len(found) == 1, result.stdout
    assert parse_url(found[0]["url"]).params["port"] == private_bus.rpartition("=")[2]


@pytest.mark.udp_multicast
def test_monitor_watches_the_urls_port(private_bus: str) -> None:
    """A frame of random bytes sent on the private port only: no other process can send it on another."""
    marker = os.urandom(8)
    port = int(private_bus.rpartition("=")[2])
    proc = subprocess.Popen(
        [sys.executable, "-m", "grippers", "monitor", private_bus, "--json", "--duration", "120"],
        cwd=ROOT,
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,
        text=True,
    )
    seen = threading.Event()

    def read() -> None:
        assert proc.stdout is not None
        for line in proc.stdout:
            if json.loads(line).get("raw") == marker.hex():
                seen.set()

    reader = threading.Thread(target=read, daemon=True)
    reader.start()
    # command 63, which no STEPFOC command uses, to our node: the simulator ignores it, the monitor shows it
    frame = can.Message(arbitration_id=NODE << 7 | 63 << 1, data=marker, is_extended_id=False)
    try:
        with can.Bus(interface="udp_multicast", channel=GROUP, port=port) as bus:
            deadline = time.monotonic() + 60
            # Send until the monitor shows the frame (it joins the bus once it has started).
            while not seen.is_set() and time.monotonic() < deadline and proc.poll() is None:
                bus.send(frame)
                seen.wait(0.2)
    finally:
        proc.send_signal(signal.SIGINT)
        _, err = proc.communicate(timeout=30)
        reader.join(5)
    assert seen.is_set(), f"the monitor did not see the frame sent on the URL's port: {err}"
