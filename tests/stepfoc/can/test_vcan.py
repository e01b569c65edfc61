"""The client against the simulator over SocketCAN ``vcan0`` (``scripts/setup-vcan.sh``), when it exists.

Skipped with a reason where the interface is missing (containers, macOS, Windows, kernels without vcan).
"""

from __future__ import annotations

import os
import sys

import pytest

from grippers.drivers.stepfoc.can_client import StepfocBus
from grippers.drivers.stepfoc.can_protocol import Detection
from grippers.drivers.stepfoc.sim import MsgModel, serve_can

pytestmark = pytest.mark.vcan


def _vcan_reason() -> str | None:
    if not sys.platform.startswith("linux"):
        return "SocketCAN exists only on Linux"
    if not os.path.exists("/sys/class/net/vcan0"):
        return "no vcan0 interface (run scripts/setup-vcan.sh where the kernel has the vcan module)"
    return None


@pytest.fixture
def vcan() -> str:
    reason = _vcan_reason()
    if reason:
        pytest.skip(reason)
    return "vcan0"


def test_vcan_calibrate_and_move(vcan: str) -> None:
    with (
        serve_can([MsgModel(node=9)], f"can://socketcan/{vcan}", time_scale=200.0),
        StepfocBus(interface="socketcan", channel=vcan) as bus,
    ):
        node = bus.node(9, timeout=1.0)
        assert node.ping()
        assert node.calibrate(timeout=10.0).calibrated
        assert node.move(50, 255, timeout=10.0).detection is Detection.AT_POSITION
        node.estop()
        assert node.poll().estop_error and node.last_error_bit
        assert not node.clear_error().estop_error
