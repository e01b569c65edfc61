"""StepfocBus / StepfocNode against the simulator on python-can ``virtual`` buses (one channel per test)."""

from __future__ import annotations

import threading
import time
from collections.abc import Callable

import can
import pytest

from grippers.drivers.errors import CommandFailed, ConnectionLost, GripperTimeout, LimitError, ProtocolError
from grippers.drivers.stepfoc.can_client import StepfocBus, open_node
from grippers.drivers.stepfoc.can_protocol import (
    Cmd,
    Detection,
    GripperCommand,
    decode_frame,
    encode_command,
    pack_id,
)
from grippers.drivers.stepfoc.sim import MsgModel
from grippers.drivers.stepfoc.sim.can_server import CanSimServer


def test_poll_and_driver_queries(sim: CanSimServer, canbus: StepfocBus) -> None:
    node = canbus.node(0, timeout=5.0)  # values, not timing: a starved simulator answered after 0.5 s (CI N6)
    st = node.poll()
    # power-up detection is 3 (STEPFOC common.h), whatever the jaws do
    assert not st.calibrated and st.detection is Detection.AT_POSITION and not node.last_error_bit
    assert node.ping()
    info = node.device_info()
    assert (info.hardware_version, info.software_version, info.serial) == (1, 12, 100_001)
    assert node.temperature() == 31
    assert node.bus_voltage() == 24_000
    assert abs(node.iq()) < 80  # no drive current: the offset and noise of the reading only
    assert node.encoder().position == sim.model.ticks
    assert not node.error_state().error
    assert sim.url == f"stepfoc+can://virtual/{sim.channel}?node=0"


def test_calibrate_then_move_with_part(start_sim: Callable[..., CanSimServer], canbus: StepfocBus) -> None:
    server = start_sim(MsgModel(node=0, part_width_mm=40.0))
    node = canbus.node(0, current_limit_ma=700)
    st = node.calibrate(timeout=5.0)
    assert st is not None and st.calibrated and st.position == 255
    st = node.move(128, 255, 500, timeout=5.0)
    assert st.detection is Detection.AT_POSITION and st.position == 127  # truncation (docs/protocols.md §2)
    st = node.move(0, 255, timeout=5.0)
    assert st.position == 0 and st.detection is Detection.AT_POSITION
    st = node.move(255, 255, 600, timeout=5.0)
    assert st.detection is Detection.CLOSING_OBJECT and st.current_ma < -480
    assert server.model.opening_mm == pytest.approx(40.0)


def test_move_refused_when_uncalibrated(sim: CanSimServer, canbus: StepfocBus) -> None:
    with pytest.raises(CommandFailed, match="not calibrated"):
        canbus.node(0).move(100, 100)


def test_current_is_clamped_to_the_limit(sim: CanSimServer, canbus: StepfocBus) -> None:
    node = canbus.node(0, current_limit_ma=400)
    node.command(10, 20, 2800)
    assert sim.model.current_setpoint == 400
    node.command(11, 20)  # default: the limit
    assert sim.model.current_setpoint == 400


@pytest.mark.parametrize(
    ("position", "speed", "current"),
    [(256, 0, 100), (-1, 0, 100), (0, 256, 100), (0, -3, 100), (0, 0, -1), (1.5, 0, 100)],
)
def test_out_of_range_refused_before_sending(
    sim: CanSimServer,
    canbus: StepfocBus,
    spy: can.BusABC,
    drain_frames: Callable[..., list[can.Message]],
    position: int,
    speed: int,
    current: int,
) -> None:
    with pytest.raises(LimitError):
        canbus.node(0).command(position, speed, current)
    assert drain_frames(spy) == []


@pytest.mark.parametrize("node", [16, -1])
def test_node_out_of_range(canbus: StepfocBus, node: int) -> None:
    with pytest.raises(LimitError):
        canbus.node(node)


def test_silent_node_times_out_naming_node_and_command(sim: CanSimServer, canbus: StepfocBus) -> None:
    sim.faults.silent = True
    with pytest.raises(GripperTimeout) as info:
        canbus.node(0, timeout=0.1).poll()
    assert "node 0" in str(info.value) and info.value.command == "poll"
    assert isinstance(info.value, TimeoutError)
    assert not canbus.node(0).ping(timeout=0.1)


def test_absent_node_times_out(sim: CanSimServer, canbus: StepfocBus) -> None:
    with pytest.raises(GripperTimeout, match="node 7"):
        canbus.node(7).device_info(timeout=0.1)


def test_dropped_reply_then_recovery(sim: CanSimServer, canbus: StepfocBus) -> None:
    sim.faults.drop_replies(1)
    node = canbus.node(0, timeout=0.1)
    with pytest.raises(GripperTimeout):
        node.poll()
    assert node.poll().position == 249  # encoder 0 against the default stops 10329 / -229


def test_error_bit_fault_is_surfaced(sim: CanSimServer, canbus: StepfocBus) -> None:
    node = canbus.node(0)
    sim.faults.error_bit_replies(1)
    st = node.poll()
    assert st.error_bit and node.last_error_bit and not st.estop_error
    assert not node.poll().error_bit and not node.last_error_bit


def test_truncated_reply_is_a_protocol_error(sim: CanSimServer, canbus: StepfocBus) -> None:
    sim.faults.truncate_replies(1)
    with pytest.raises(ProtocolError, match="2 data bytes, expected 4"):
        canbus.node(0).poll()


def test_estop_during_move(start_sim: Callable[..., CanSimServer], canbus: StepfocBus) -> None:
    server = start_sim(MsgModel(node=0), time_scale=20.0)
    node = canbus.node(0)
    node.calibrate(timeout=5.0)
    node.command(0, 0)  # slowest speed: ~42 simulated s for the stroke
    node.estop()
    st = node.poll()
    # command 0 sets the driver's e-stop error only: the error bit, not the 60 frame's flag; 26 names it
    assert not st.estop_error and st.error_bit and node.last_error_bit and node.fault(st) == "estop"
    stopped_at = server.model.ticks
    with pytest.raises(CommandFailed, match="estop"):
        node.wait_motion(timeout=1.0)
    assert server.model.ticks == stopped_at
    es = node.error_state()
    assert es.estop and es.error


def test_clear_error_trap(sim: CanSimServer, canbus: StepfocBus) -> None:
    node = canbus.node(0)
    node.command(50, 50, 300, estop=True)
    assert node.poll().estop_error
    node.send(Cmd.CLEAR_ERROR)  # 1 alone: the stored command still has estop, so the error returns
    assert node.poll().estop_error
    st = node.clear_error()
    assert not st.estop_error and not st.error_bit and not st.action
    assert not node.poll().estop_error
    assert sim.model.estop is False


def test_clear_error_without_known_command(sim: CanSimServer, canbus: StepfocBus) -> None:
    node = canbus.node(0)
    node.estop()
    assert node.fault(node.poll()) == "estop"
    st = canbus.node(0).clear_error()
    assert not st.estop_error and not st.error_bit


def test_send_failure_is_connection_lost(channel: str) -> None:
    raw = can.Bus(interface="virtual", channel=channel)
    bus = StepfocBus(raw)
    try:
        raw.shutdown()
        with pytest.raises(ConnectionLost):
            bus.node(0).poll()
    finally:
        bus.close()


def test_closed_bus_refuses(sim: CanSimServer, channel: str) -> None:
    bus = StepfocBus(interface="virtual", channel=channel)
    node = bus.node(0)
    bus.close()
    bus.close()  # idempotent
    with pytest.raises(ConnectionLost):
        node.poll()


def test_given_bus_is_not_closed(channel: str) -> None:
    raw = can.Bus(interface="virtual", channel=channel)
    with StepfocBus(raw):
        pass
    raw.send(can.Message(arbitration_id=1, is_extended_id=False))  # still open
    raw.shutdown()


def test_several_nodes_one_bus_concurrently(
    start_sim: Callable[..., CanSimServer], canbus: StepfocBus
) -> None:
    start_sim(*(MsgModel(node=n, serial=1000 + n) for n in (1, 2, 3)))
    errors: list[BaseException] = []

    def work(n: int) -> None:
        try:
            node = canbus.node(n)
            for _ in range(20):
                assert node.device_info().serial == 1000 + n
                assert node.poll() is not None
            node.calibrate(timeout=5.0)
            assert node.move(100 + n, 255, timeout=5.0).detection is Detection.AT_POSITION
        except BaseException as exc:  # noqa: BLE001
            errors.append(exc)

    threads = [threading.Thread(target=work, args=(n,)) for n in (1, 2, 3)]
    for t in threads:
        t.start()
    for t in threads:
        t.join(10)
    assert errors == []
    span = 21000  # 105 mm x 200 ticks/mm; both mappings truncate (docs/protocols.md §2)
    expected = [((100 + n) * span // 255) * 255 // span for n in (1, 2, 3)]
    assert expected == [100, 102, 102]
    assert [canbus.node(n).poll().position for n in (1, 2, 3)] == expected


def test_same_node_from_two_threads(sim: CanSimServer, canbus: StepfocBus) -> None:
    node = canbus.node(0)
    results: list[object] = []

    def work() -> None:
        for _ in range(30):
            results.append(node.poll(timeout=1.0))

    threads = [threading.Thread(target=work) for _ in range(2)]
    for t in threads:
        t.start()
    for t in threads:
        t.join(10)
    assert len(results) == 60


def test_set_node_id(sim: CanSimServer, canbus: StepfocBus) -> None:
    node = canbus.node(0)
    node.set_node_id(6)
    assert node.node == 6 and node.poll() is not None
    assert sim.model.node == 6
    assert not canbus.node(0).ping(timeout=0.1)
    with pytest.raises(LimitError):
        node.set_node_id(16)


def test_heartbeat(sim: CanSimServer, canbus: StepfocBus) -> None:
    node = canbus.node(0)
    node.heartbeat(50)  # simulated ms
    first = node.wait_heartbeat(timeout=1.0)
    assert node.wait_heartbeat(timeout=1.0) > first
    node.heartbeat(0)


def test_other_hosts_frames_and_poll_during_calibration(
    start_sim: Callable[..., CanSimServer],
    canbus: StepfocBus,
    spy: can.BusABC,
) -> None:
    server = start_sim(MsgModel(node=0), time_scale=20.0)
    node = canbus.node(0)
    node.calibrate(wait=False)
    # another host's frames on the bus (a 61 poll for node 0) must not confuse our reader
    spy.send(can.Message(arbitration_id=pack_id(0, Cmd.GRIPPER_COMMAND), is_extended_id=False))
    assert node.poll().detection is Detection.AT_POSITION  # frozen at its power-up value during calibration
    assert server.model.calibrating  # polls do not abort calibration
    node.command(0, 0)  # a 5-byte 61 does
    assert not server.model.calibrating


def test_open_node_url(sim: CanSimServer) -> None:
    with open_node(sim.url) as node:
        assert node.node == 0 and node.ping()
    assert not node.bus.alive


def test_immediate_reply_has_stale_detection(
    start_sim: Callable[..., CanSimServer], canbus: StepfocBus
) -> None:
    start_sim(MsgModel(node=0))
    node = canbus.node(0)
    node.calibrate(timeout=5.0)
    assert node.move(100, 255, timeout=5.0).detection is Detection.AT_POSITION
    reply = node.command(10, 5)
    assert reply.detection is Detection.AT_POSITION  # previous value (docs/protocols.md §2)
    assert node.poll().detection is Detection.MOVING


def test_wrong_length_61_is_answered(
    sim: CanSimServer, spy: can.BusABC, drain_frames: Callable[..., list[can.Message]]
) -> None:
    spy.send(
        can.Message(arbitration_id=pack_id(0, Cmd.GRIPPER_COMMAND), data=b"\x01\x02", is_extended_id=False)
    )
    frames = drain_frames(spy, 0.3)
    assert [decode_frame(f.arbitration_id, f.data).command for f in frames] == [Cmd.GRIPPER_STATUS]


def test_repeated_command_bytes(sim: CanSimServer, canbus: StepfocBus) -> None:
    node = canbus.node(0)
    cmd = GripperCommand(9, 9, 300, True, False, False)
    node.send_command(cmd)
    assert sim.model.position_setpoint == 9
    assert encode_command(cmd) == bytes([9, 9, 1, 44, 0x80])


def test_closing_the_bus_wakes_a_waiting_request_at_once(channel: str) -> None:
    """A poll to a node nobody answers is woken by close() with ConnectionLost, not left to its timeout;
    many waiters at once, and a close racing replies, never break the reply slots."""
    bus = StepfocBus(interface="virtual", channel=channel)
    errors: list[BaseException] = []

    def wait(node: int) -> None:
        try:
            bus.node(node, timeout=5.0).poll()
        except BaseException as exc:  # noqa: BLE001 - collected for the assertion
            errors.append(exc)

    threads = [threading.Thread(target=wait, args=(n,)) for n in range(8)]
    for t in threads:
        t.start()
    time.sleep(0.1)  # every poll sent and waiting
    t0 = time.monotonic()
    bus.close()
    for t in threads:
        t.join(5)
    assert time.monotonic() - t0 < 2.5
    assert len(errors) == 8 and all(isinstance(e, ConnectionLost) for e in errors)
