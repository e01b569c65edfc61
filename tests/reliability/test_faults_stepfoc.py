"""STEPFOC/MSG faults: silent node, error bit, dropped/corrupt/truncated replies, e-stop during a move, CAN
send failures (python-can's exceptions mapped to ours) and a UART port that disappears."""

from __future__ import annotations

import time

import can
import pytest
from can.interfaces.virtual import VirtualBus

import grippers
from grippers.drivers.errors import ConnectionLost, GripperError, GripperTimeout, ProtocolError
from grippers.drivers.stepfoc.can_client import StepfocBus
from grippers.drivers.stepfoc.can_protocol import Cmd, pack_id
from grippers.drivers.stepfoc.sim import MsgModel
from grippers.drivers.stepfoc.uart_client import StepfocUart
from grippers.gripper import FastStopActive


class FailingBus(VirtualBus):
    """A virtual bus whose send raises python-can's own CanOperationError while ``fail`` is set."""

    fail = False

    def send(self, msg: can.Message, timeout: float | None = None) -> None:
        if self.fail:
            raise can.CanOperationError("injected: transmit buffer full / bus-off")
        super().send(msg, timeout)


@pytest.fixture
def node(msg_can_sim, can_channel):
    server = msg_can_sim(MsgModel(node=3))
    with StepfocBus(interface="virtual", channel=can_channel) as bus:
        yield server, bus.node(3, timeout=0.2)


def test_silent_node_times_out_naming_the_node_then_recovers(node) -> None:
    server, n = node
    assert n.ping()
    server.faults.silent = True
    with pytest.raises(GripperTimeout, match=r"node 3: poll: no reply within 0.2 s"):
        n.poll()
    assert n.ping() is False
    server.faults.silent = False
    assert n.poll().position == n.poll().position  # answers again; nothing stuck in the client


def test_absent_node_id_times_out(node, can_channel) -> None:
    _, n = node
    with pytest.raises(GripperTimeout, match="node 9"):
        n.bus.node(9, timeout=0.1).device_info()


def test_api_open_of_a_silent_node_fails_with_a_timeout(msg_can_sim) -> None:
    server = msg_can_sim(MsgModel(node=0))
    server.faults.silent = True
    with pytest.raises(GripperTimeout, match="node 0"):
        grippers.open(server.url, profile="msg-150", timeout=0.2)


def test_error_bit_is_reported_and_clears(node) -> None:
    server, n = node
    server.faults.error_bit_replies(1)
    st = n.poll()
    assert st.error_bit and n.last_error_bit
    assert not n.poll().error_bit and not n.last_error_bit


def test_api_state_reports_the_error_bit() -> None:
    with grippers.open("sim://msg-150?time_scale=200") as g:
        g.simulator.faults.error_bit_replies(1)
        assert g.state().faults == ("error",)
        assert g.state().faults == ()


@pytest.mark.parametrize("fault", ["drop", "truncate", "corrupt"])
def test_bad_status_reply_then_service_continues(node, fault: str) -> None:
    server, n = node
    getattr(server.faults, f"{fault}_replies")(1)
    if fault == "drop":
        with pytest.raises(GripperTimeout):
            n.poll()
    elif fault == "truncate":  # 2 of 4 bytes: a typed length error, at once
        with pytest.raises(ProtocolError, match=r"gripper_status: 2 data bytes, expected 4"):
            n.poll()
    else:  # one flipped flag bit decodes: CAN frames carry no checksum of ours (the bus has its CRC)
        assert n.poll() is not None
    assert n.poll(timeout=1.0).calibrated is False


def test_api_estop_from_another_host_during_a_move(can_channel) -> None:
    with grippers.open("sim://msg-150?time_scale=50") as g:
        g.home()
        handle = g.move(0.01, 0.0025, wait=False)
        other = can.Bus(interface="virtual", channel=g.simulator.channel)  # e.g. a safety controller
        try:
            other.send(can.Message(arbitration_id=pack_id(0, Cmd.ESTOP), data=b"", is_extended_id=False))
        finally:
            other.shutdown()
        with pytest.raises(FastStopActive, match="aborted: e-stop"):
            handle.wait(5.0)
        assert g.state().fast_stopped
        with pytest.raises(GripperError, match="fast stop is active"):
            g.move(0.05)
        g.acknowledge()
        assert not g.state().faults
        assert g.move(0.05).width == pytest.approx(0.05, abs=0.001)


def test_can_send_failure_maps_to_connection_lost(msg_can_sim, can_channel) -> None:
    msg_can_sim(MsgModel(node=0))
    raw = FailingBus(channel=can_channel)
    with StepfocBus(raw) as bus:
        n = bus.node(0, timeout=0.5)
        n.poll()
        raw.fail = True
        with pytest.raises(ConnectionLost, match=r"node 0: poll: send failed: injected") as info:
            n.poll()
        assert isinstance(info.value.__cause__, can.CanOperationError)
        with pytest.raises(ConnectionLost, match="send failed"):
            n.estop()
        raw.fail = False
        assert n.poll() is not None  # a transient bus error does not kill the handle
    raw.shutdown()


def test_shut_down_bus_maps_to_connection_lost(msg_can_sim, can_channel) -> None:
    msg_can_sim(MsgModel(node=0))
    raw = can.Bus(interface="virtual", channel=can_channel)
    bus = StepfocBus(raw)
    n = bus.node(0, timeout=0.5)
    n.poll()
    raw.shutdown()  # e.g. the adapter unplugged
    with pytest.raises(ConnectionLost, match="closed bus|CAN bus failed"):
        n.poll()
    deadline = time.monotonic() + 2.0
    while bus.alive and time.monotonic() < deadline:  # the reader notices within its receive poll
        time.sleep(0.01)
    assert not bus.alive
    with pytest.raises(ConnectionLost, match="CAN bus failed"):
        n.device_info()
    bus.close()


def test_wsg_over_can_send_failure_maps_to_connection_lost(wsg_sim, can_channel) -> None:
    from grippers.drivers.wsg.client import WsgClient

    wsg_sim(f"can://virtual/{can_channel}")
    raw = FailingBus(channel=can_channel)
    with WsgClient.can(bus=raw, timeout=0.5) as c:
        assert c.loop(b"ok") == b"ok"
        raw.fail = True
        with pytest.raises(ConnectionLost, match="send failed: injected"):
            c.loop(b"no")
    raw.shutdown()


def test_uart_port_that_disappears(msg_uart_sim) -> None:
    server = msg_uart_sim()
    client = StepfocUart(server.url, timeout=0.3)
    assert client.gripper() == 1
    server.faults.request_close()  # the simulator closes both pty ends: the port is gone
    with pytest.raises(ConnectionLost, match="serial port failed"):
        for _ in range(20):  # the first exchange may still be answered before the close lands
            client.position()
    assert client.closed
    with pytest.raises(ConnectionLost, match="closed"):
        client.gripper()


@pytest.mark.parametrize("fault", ["drop", "truncate", "corrupt", "garbage"])
def test_uart_bad_answer_then_service_continues(msg_uart_sim, fault: str) -> None:
    server = msg_uart_sim()
    with StepfocUart(server.url, timeout=0.3) as client:
        if fault == "garbage":
            server.faults.send_garbage(b"\xff\x00noise\r\n#Gripper 1\r\nGripper: x\r\n")
            assert client.position() == server.model.position
        else:
            getattr(server.faults, f"{fault}_replies")(1)
            with pytest.raises(GripperTimeout):
                client.position()
        assert client.gripper() == 1


def test_delayed_reply_times_out_and_the_next_request_gets_a_value_of_its_kind(node) -> None:
    """CAN replies carry no sequence number: a late reply can answer the next request with the same key
    (docs/protocols.md §2; documented in can_client). It is always the same kind of value, never another's."""
    server, n = node
    server.faults.delay_replies(0.4)
    with pytest.raises(GripperTimeout, match="device_info: no reply within 0.2 s"):
        n.device_info()
    assert n.temperature(timeout=1.0) == server.model.temperature_c  # other keys are unaffected
    assert n.device_info(timeout=1.0).serial == server.model.serial
    time.sleep(0.5)
    assert n.device_info().serial == server.model.serial
