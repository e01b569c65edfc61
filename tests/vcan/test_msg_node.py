"""The MSG node client against the simulator over SocketCAN ``vcan0``: raw frames, several nodes, errors.

Skipped with a reason where the interface is missing (run ``scripts/run-vcan-tests.sh``). Node ids 9, 10-12.
"""

from __future__ import annotations

import threading

import can
import pytest

from grippers.drivers.stepfoc.can_client import StepfocBus
from grippers.drivers.stepfoc.can_protocol import Detection
from grippers.drivers.stepfoc.sim import MsgModel, serve_can

pytestmark = pytest.mark.vcan


def test_calibrate_move_estop_and_clear(vcan: str) -> None:
    with (
        serve_can([MsgModel(node=9)], f"can://socketcan/{vcan}", time_scale=200.0),
        StepfocBus(interface="socketcan", channel=vcan) as bus,
    ):
        node = bus.node(9, timeout=1.0)
        assert node.ping()
        assert node.calibrate(timeout=10.0).calibrated
        assert node.move(50, 255, timeout=10.0).detection is Detection.AT_POSITION
        node.estop()
        # Command 0 sets the DRIVER's e-stop: the identifier's error bit and frame 26, not the 60 frame's
        # estop flag (STEPFOC firmware, docs/protocols.md §2 "Firmware behaviour a client must survive").
        st = node.poll()
        assert st.error_bit and not st.estop_error
        assert node.error_state().estop
        assert node.fault(st) == "estop"
        cleared = node.clear_error()
        assert not cleared.error_bit and node.fault(cleared) is None


def test_three_nodes_move_at_once(vcan: str) -> None:
    nodes = (10, 11, 12)
    with (
        serve_can([MsgModel(node=n) for n in nodes], f"can://socketcan/{vcan}", time_scale=200.0),
        StepfocBus(interface="socketcan", channel=vcan) as bus,
    ):
        handles = [bus.node(n, timeout=1.0) for n in nodes]
        for h in handles:
            assert h.calibrate(timeout=10.0).calibrated
        results: dict[int, object] = {}

        def go(h, target: int) -> None:
            try:
                results[target] = h.move(target, 200, timeout=10.0).position
            except Exception as exc:  # noqa: BLE001 - reported below
                results[target] = exc

        threads = [threading.Thread(target=go, args=(h, 40 + 60 * i)) for i, h in enumerate(handles)]
        for t in threads:
            t.start()
        for t in threads:
            t.join(30)
        # each node reached its own target: replies were matched by node id, none crossed over
        assert {t: abs(p - t) <= 5 for t, p in results.items() if isinstance(p, int)} == {
            40: True,
            100: True,
            160: True,
        }


def test_error_frames_are_ignored_and_the_client_carries_on(vcan: str) -> None:
    """Error frames (a controller's bus-off, error-passive, lost arbitration notices) reach every socket that
    asks for them; python-can's socketcan bus does. They carry no protocol frame, so the client must neither
    take one for a reply nor stop reading."""
    with (
        serve_can([MsgModel(node=13)], f"can://socketcan/{vcan}", time_scale=200.0),
        StepfocBus(interface="socketcan", channel=vcan) as bus,
        can.Bus(interface="socketcan", channel=vcan) as raw,
    ):
        seen: list[can.Message] = []
        bus.subscribe(lambda m: seen.append(m) if m.is_error_frame else None)
        node = bus.node(13, timeout=1.0)
        assert node.ping()
        # linux/can/error.h: CAN_ERR_BUSOFF 0x40, CAN_ERR_CRTL 0x04 (data[1] 0x10: error passive), CAN_ERR_ACK
        for err_class, data in (
            (0x40, bytes(8)),
            (0x04, bytes([0, 0x10, 0, 0, 0, 0, 0, 0])),
            (0x20, bytes(8)),
        ):
            raw.send(
                can.Message(arbitration_id=err_class, is_error_frame=True, is_extended_id=True, data=data)
            )
            st = node.poll()
            assert not st.error_bit
        assert len(seen) == 3 and bus.alive
        assert node.calibrate(timeout=10.0).calibrated
