"""MSG over python-can's udp_multicast bus: the simulator process is killed and restarted on the same bus.

Run under ``flock /tmp/grippers-udp-mcast.lock`` (host-wide bus, docs/protocols.md §2 "Testing without CAN
hardware"); a random node id keeps this test apart from others on the bus anyway.
"""

from __future__ import annotations

import random
import time
from collections.abc import Callable

import pytest

import grippers
from grippers import ConnectionLost

from .conftest import FAST, Restartable

pytest.importorskip("msgpack")  # python-can's udp_multicast needs it
pytestmark = pytest.mark.udp_multicast

GROUP = "239.74.163.2"  # python-can's IPv4 default group (administratively scoped)


def test_msg_node_killed_and_restarted_on_the_same_bus(restartable: Callable[..., Restartable]) -> None:
    node = random.randint(1, 15)
    sim = restartable("msg", "--listen", f"can://udp_multicast/{GROUP}?node={node}", "--time-scale", "50")
    events: list[bool] = []
    url = f"stepfoc+can://udp_multicast/{GROUP}?node={node}&reconnect=true&{FAST}"
    with grippers.open(url, timeout=0.1) as g:
        g.on_connection(events.append)
        g.home()
        assert g.state().referenced
        sim.kill()
        deadline = time.monotonic() + 10
        while g.connected:  # a silent node: two missed heartbeats
            assert time.monotonic() < deadline
            time.sleep(0.01)
        with pytest.raises(ConnectionLost):
            g.state()
        sim.start()
        while not (g.connected and len(events) >= 2):  # listeners are told after the flag turns
            assert time.monotonic() < deadline + 10
            time.sleep(0.01)
        assert events == [False, True]
        st = g.state()
        assert not st.referenced  # a power-cycled MSG has lost its calibration (docs/protocols.md §2)
        g.home()
        assert abs(g.move(0.05).width - 0.05) < 2e-3
