"""The client against the simulator in ANOTHER process over python-can's ``udp_multicast`` bus.

python-can binds every such bus to one UDP port and, on Linux, a socket receives every group joined on the
host (docs/protocols.md §2, "Testing without CAN hardware"), so each test uses its own port AND its own node
ids, and the tests stay few. The simulator runs in a subprocess (``python -c`` calling ``serve_can``).
"""

from __future__ import annotations

import logging
import subprocess
import sys
from collections.abc import Callable, Iterator

import pytest

from grippers.drivers.errors import GripperTimeout
from grippers.drivers.stepfoc.can_client import StepfocBus, open_node
from grippers.drivers.stepfoc.can_protocol import Detection
from tests.mcast import private_port

pytest.importorskip("msgpack")  # python-can's udp_multicast needs it
pytestmark = pytest.mark.udp_multicast

GROUP = "239.74.163.2"  # python-can's IPv4 default group (administratively scoped)

SCRIPT = """
import sys
from grippers.drivers.stepfoc.sim import MsgModel, serve_can
nodes = [int(n) for n in sys.argv[2].split(",")]
server = serve_can([MsgModel(node=n, part_width_mm=50.0) for n in nodes], sys.argv[1], time_scale=200.0)
print(server.url, flush=True)
sys.stdin.read()  # runs until the test closes our stdin
server.close()
"""


@pytest.fixture
def remote_sim() -> Iterator[Callable[[list[int]], str]]:
    procs: list[subprocess.Popen[str]] = []

    def start(nodes: list[int]) -> str:
        port = private_port()
        listen = f"can://udp_multicast/{GROUP}?port={port}"
        proc = subprocess.Popen(
            [sys.executable, "-c", SCRIPT, listen, ",".join(map(str, nodes))],
            stdin=subprocess.PIPE,
            stdout=subprocess.PIPE,
            stderr=subprocess.PIPE,
            text=True,
        )
        procs.append(proc)
        assert proc.stdout is not None
        line = proc.stdout.readline()
        if not line:
            pytest.skip(f"udp_multicast simulator did not start: {proc.stderr.read() if proc.stderr else ''}")
        assert line.startswith("stepfoc+can://udp_multicast/")
        return f"stepfoc+can://udp_multicast/{GROUP}?port={port}"

    yield start
    for proc in procs:
        assert proc.stdin is not None
        proc.stdin.close()
        try:
            proc.wait(timeout=5)
        except subprocess.TimeoutExpired:
            proc.kill()
            proc.wait()


def test_remote_simulator_calibrate_and_grip(remote_sim: Callable[[list[int]], str]) -> None:
    url = remote_sim([11])
    with open_node(url + "&node=11", timeout=1.0) as node:
        assert node.ping(timeout=2.0)
        assert node.calibrate(timeout=10.0).calibrated
        assert node.move(0, 255, 500, timeout=10.0).detection is Detection.AT_POSITION
        st = node.move(255, 255, 500, timeout=10.0)
        assert st.detection is Detection.CLOSING_OBJECT and st.current_ma < 0


def test_remote_two_nodes_one_bus(remote_sim: Callable[[list[int]], str]) -> None:
    url = remote_sim([13, 14])
    bus, _ = StepfocBus.from_url(url)
    with bus:
        a, b = bus.node(13, timeout=1.0), bus.node(14, timeout=1.0)
        assert a.ping(timeout=2.0) and b.ping(timeout=2.0)
        a.estop()
        assert a.fault(a.poll()) == "estop" and a.last_error_bit
        assert b.fault(b.poll()) is None and not b.last_error_bit
        assert not a.clear_error().error_bit
        with pytest.raises(GripperTimeout):
            bus.node(15).poll(timeout=0.2)


def test_the_api_takes_the_port_as_the_driver_does(remote_sim: Callable[[list[int]], str]) -> None:
    """Issue 12 §4: ``port=`` on a ``stepfoc+can://udp_multicast/…`` URL reaches the bus (it was refused or
    dropped, so the API could not reach a simulator on a private port)."""
    import grippers

    url = remote_sim([12])
    with grippers.open(url + "&node=12&profile=msg-150&timeout=1.0") as g:
        assert g.info().extra["node"] == 12
        assert g.state().width >= 0


def test_a_sent_frame_is_logged_once_although_the_bus_hands_it_back(caplog: pytest.LogCaptureFixture) -> None:
    """Issue 33 §3: ``-vv`` on ``udp_multicast`` logged every sent frame twice, once as it went out and once
    as our own multicast echo came back. The echo is now recognised (can_session.py) and not logged again;
    the node's reply is still logged. In-process simulator, node 13 on a private port."""
    from grippers.drivers.stepfoc.sim import MsgModel, serve_can

    channel = f"udp_multicast/{GROUP}?port={private_port()}"
    server = serve_can([MsgModel(node=13)], f"can://{channel}", time_scale=20.0)
    try:
        with (
            caplog.at_level(logging.DEBUG, logger="grippers.wire"),
            open_node(f"stepfoc+can://{channel}&node=13", timeout=2.0) as node,
        ):
            node.poll()
            wire = [r.getMessage() for r in caplog.records if r.name == "grippers.wire"]
    finally:
        server.close()
    polls = [line for line in wire if "gripper_command poll" in line]
    assert len(polls) == 1 and "->" in polls[0], wire  # was 2: the poll sent, and its echo received
    assert any("<-" in line and "gripper_status" in line for line in wire), wire  # the reply is logged
