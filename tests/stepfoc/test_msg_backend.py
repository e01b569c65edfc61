"""The MSG client and backend against the firmware-faithful simulator (issue 12 §2, §3 for the MSG, §4):
calibrations that really end, first motions that really move, e-stops from anywhere, motions that end honestly
(never "done" when stopped, superseded or idled), and the warning when the model is assumed."""

from __future__ import annotations

import contextlib
import threading
import time
import uuid
from collections.abc import Iterator

import can
import pytest

import grippers
from grippers.drivers.errors import CommandFailed, ProtocolError
from grippers.drivers.stepfoc.can_client import StepfocBus, StepfocNode
from grippers.drivers.stepfoc.can_protocol import Cmd, GripperCommand, encode_command, pack_id
from grippers.drivers.stepfoc.sim import MsgModel, serve_can
from grippers.drivers.stepfoc.sim.can_server import CanSimServer
from grippers.drivers.stepfoc.sim.model import Phase
from grippers.gripper import FastStopActive
from tests.simhold import MSG_CREEP_S, held, step_until, under_way

TRANSPORTS = ["can", "pty"]


def sim(transport: str, time_scale: float = 20.0, **query: object) -> grippers.Gripper:
    extra = "".join(f"&{k}={v}" for k, v in query.items())
    return grippers.open(f"sim://msg-150?time_scale={time_scale}&transport={transport}{extra}")


def other_host(g: grippers.Gripper) -> can.BusABC:
    """Another program on the simulator's CAN bus (a safety controller, a second script)."""
    return can.Bus(interface="virtual", channel=g.simulator.channel)


def send_raw(g: grippers.Gripper, command: int, data: bytes = b"") -> None:
    bus = other_host(g)
    try:
        bus.send(can.Message(arbitration_id=pack_id(0, command), data=data, is_extended_id=False))
    finally:
        bus.shutdown()


@contextlib.contextmanager
def calibrated_node() -> Iterator[tuple[CanSimServer, StepfocNode]]:
    """Node 0 simulated on a fresh virtual bus at 50x, calibrated, with this test's client handle to it."""
    channel = f"msg-backend-{uuid.uuid4().hex[:8]}"
    with (
        serve_can([MsgModel(node=0)], f"can://virtual/{channel}", time_scale=50.0) as server,
        StepfocBus(interface="virtual", channel=channel) as bus,
    ):
        node = bus.node(0)
        node.calibrate(timeout=5.0)
        yield server, node


FIRST = 0.002  # m: where first_motion() leaves the jaws


def first_motion(g: grippers.Gripper) -> None:
    """A handle's first motion goes out as two 61s (send_command's primer): make it here, so the motion a
    test holds still is a single 61 and cannot be sent again after what the test does meanwhile."""
    assert g.move(FIRST).width == pytest.approx(FIRST, abs=0.001)


# ------------------------------------------------------------------------------ calibration (§2)


@pytest.mark.parametrize("transport", TRANSPORTS)
def test_home_on_a_calibrated_gripper_waits_for_the_real_end(transport: str) -> None:
    with sim(transport) as g:
        g.home()
        g.move(0.05)
        model = g.simulator.model
        g.home()  # the calibrated bit stays set: the old client returned at once
        assert not model.calibrating
        assert model.opening_mm == pytest.approx(0.0, abs=0.1)  # calibration ends at the closed stop
        assert g.state().width == pytest.approx(0.0, abs=0.001)


@pytest.mark.parametrize("transport", TRANSPORTS)
def test_home_sends_no_motion_command_while_calibrating(transport: str) -> None:
    with sim(transport) as g:
        g.home()
        g.move(0.05)
        model = g.simulator.model
        calls: list[str] = []
        for name in ("on_command", "set_position"):
            original = getattr(model, name)

            def spy(*a: object, _o=original, _n=name, **k: object) -> object:
                calls.append(_n)
                return _o(*a, **k)

            setattr(model, name, spy)
        g.home()
        assert calls == []


@pytest.mark.parametrize("transport", TRANSPORTS)
def test_the_first_motion_after_a_calibration_really_moves(transport: str) -> None:
    with sim(transport) as g:
        g.home()
        assert g.move(0.05).width == pytest.approx(0.05, abs=0.001)
        g.home()  # the jaws rest closed; the node kept the last 61's bytes
        result = g.move(0.05)  # the same motion again: must not be taken for "already there"
        assert result.width == pytest.approx(0.05, abs=0.001)
        assert g.simulator.model.opening_mm == pytest.approx(50.0, abs=1.0)


def test_calibration_watch_needs_the_jaws_to_leave_and_come_back() -> None:
    with calibrated_node() as (server, node):
        assert server.model.calibrated and not server.model.calibrating
        node.move(128, 255, timeout=5.0)
        node.calibrate(timeout=5.0)
        assert not server.model.calibrating and node.poll().position == 255


def test_the_client_never_repeats_a_motion_61_byte_for_byte() -> None:
    with calibrated_node() as (server, node):
        node.move(100, 200, timeout=5.0)
        before = server.model._last_command
        node.calibrate(timeout=5.0)  # the node keeps those bytes over the calibration
        node.command(100, 200)
        assert server.model._last_command != before  # so the at-position latch was reset ...
        st = node.wait_motion(timeout=5.0)
        assert abs(st.position - 100) <= 1 and server.model.opening_mm < 70  # ... and the jaws really moved


def test_wait_motion_ends_by_the_tracker_not_at_someone_else_s_target() -> None:
    """Issue 32: ``wait_motion`` said "done" at any detection but MOVING, so a motion another host sent
    elsewhere (detection 3 at ITS target) ended ours as arrived. The tracker's rule: 3 counts only at our
    target; jaws at rest elsewhere are a motion stopped by someone else."""
    elsewhere = GripperCommand(180, 255, 500, activate=True, action=True, estop=False)
    with calibrated_node() as (server, node):
        with held(server, creep=MSG_CREEP_S) as clock:
            start = node.poll().position
            node.command(0, 5)  # a slow open: seconds of device time
            step_until(clock, lambda: node.poll().position != start, "the motion under way", step=0.1)
            other = can.Bus(interface="virtual", channel=server.channel)  # another host on the bus
            try:
                frame = encode_command(elsewhere)
                other.send(
                    can.Message(
                        arbitration_id=pack_id(0, Cmd.GRIPPER_COMMAND), data=frame, is_extended_id=False
                    )
                )
            finally:
                other.shutdown()
        with pytest.raises(CommandFailed, match="stopped at position"):
            node.wait_motion(timeout=10.0)
        assert abs(server.model.position - 180) <= 2


# ------------------------------------------------------------------------------ e-stop from anywhere (§2)


def test_command_0_from_another_host_is_a_fast_stop_and_acknowledge_recovers() -> None:
    with sim("can") as g:
        g.home()
        first_motion(g)
        with held(g, creep=MSG_CREEP_S) as clock:  # the move still runs when the e-stop comes (issue 33 §5)
            handle = g.move(0.09, 0.0025, wait=False)
            step_until(clock, under_way(g, FIRST), "the move under way")
            send_raw(g, Cmd.ESTOP)
        with pytest.raises(FastStopActive, match="e-stop") as stopped:
            handle.wait(5.0)
        assert str(stopped.value).count(g.name) == 1  # named once, not with the driver's prefix again
        # latched by the motion that saw it: refused before anything is sent, no state read needed
        with pytest.raises(FastStopActive, match="call acknowledge"):
            g.move(0.03)
        assert g.state().fast_stopped
        g.acknowledge()
        assert not g.state().faults
        assert g.move(0.03).width == pytest.approx(0.03, abs=0.001)


def test_a_61_with_the_estop_bit_from_another_host_is_a_fast_stop() -> None:
    with sim("can") as g:
        g.home()
        first_motion(g)
        with held(g, creep=MSG_CREEP_S) as clock:
            handle = g.move(0.09, 0.0025, wait=False)
            step_until(clock, under_way(g, FIRST), "the move under way")
            send_raw(g, Cmd.GRIPPER_COMMAND, encode_command(GripperCommand(0, 0, 100, True, False, True)))
        with pytest.raises(FastStopActive):
            handle.wait(5.0)
        g.acknowledge()  # 61 with estop 0 first, then 1: the error does not come back
        assert g.move(0.03).width == pytest.approx(0.03, abs=0.001)


def test_clear_error_resume_resends_the_motion() -> None:
    with calibrated_node() as (server, node):
        # about 12 s of device time, held still running at the e-stop
        with held(server, creep=MSG_CREEP_S) as clock:
            start = node.poll().position
            node.command(0, 5)
            step_until(clock, lambda: node.poll().position != start, "the motion under way", step=0.1)
            node.estop()
            stopped = server.model.ticks
        node.clear_error(resume=True)
        st = node.wait_motion(timeout=5.0)
        assert st.position == 0 and server.model.ticks != stopped


def test_two_devices_with_one_node_id_are_an_error_naming_the_node() -> None:
    channel = f"msg-backend-{uuid.uuid4().hex[:8]}"
    a = serve_can([MsgModel(node=5)], f"can://virtual/{channel}", time_scale=50.0)
    b = serve_can([MsgModel(node=5, start_mm=10.0)], f"can://virtual/{channel}", time_scale=50.0)
    try:
        with StepfocBus(interface="virtual", channel=channel) as bus:
            node = bus.node(5)
            with pytest.raises(ProtocolError, match="two devices answer as node 5"):
                for _ in range(20):
                    node.poll()
                    time.sleep(0.01)
    finally:
        a.close()
        b.close()


# ------------------------------------------------------------------------------ honest endings (§3)


@pytest.mark.parametrize("transport", TRANSPORTS)
def test_a_newer_motion_supersedes_the_waiting_one(transport: str) -> None:
    with sim(transport) as g:
        g.home()
        first_motion(g)
        with held(g, creep=MSG_CREEP_S) as clock:
            handle = g.move(0.09, 0.0025, wait=False)
            step_until(clock, under_way(g, FIRST), "the move under way")
            newer = g.move(0.01, wait=False)
        second = newer.wait(10.0)
        assert second.width == pytest.approx(0.01, abs=0.001)
        with pytest.raises(CommandFailed, match="superseded"):
            handle.wait(5.0)


@pytest.mark.parametrize("transport", TRANSPORTS)
def test_stop_from_another_thread_aborts_the_blocking_motion(transport: str) -> None:
    with sim(transport) as g:
        g.home()
        model = g.simulator.model

        def stop_once_moving() -> None:
            # not a fixed delay: on a loaded machine the move may start late, and a stop sent before it would
            # only stop nothing (issue 23 §1: the test must hold under load)
            deadline = time.monotonic() + 30.0
            while time.monotonic() < deadline and model.phase not in (Phase.STARTING, Phase.MOVING):
                time.sleep(0.002)
            g.stop()

        stopper = threading.Thread(target=stop_once_moving, daemon=True)
        stopper.start()
        with pytest.raises(CommandFailed, match="aborted"):
            g.move(0.09, 0.0025)
        stopper.join(5.0)
        assert not g.state().moving


def test_a_motion_superseded_by_another_program_never_reports_success_elsewhere() -> None:
    """Issue 23 §1 (MSG): a move(100 mm) returned success at 30.5 mm when another program sent the jaws
    there: detection 3 counts only at this motion's own target."""
    with sim("can") as g:
        g.home()
        first_motion(g)
        other = GripperCommand(180, 255, 500, activate=True, action=True, estop=False)  # about 31 mm
        with held(g, creep=MSG_CREEP_S) as clock:
            handle = g.move(0.1, 0.0025, wait=False)
            step_until(clock, under_way(g, FIRST), "the move under way")
            send_raw(g, Cmd.GRIPPER_COMMAND, encode_command(other))
        with pytest.raises(CommandFailed, match="aborted"):
            handle.wait(10.0)
        assert g.simulator.model.opening_mm == pytest.approx(31.0, abs=1.0)


def test_stop_from_another_program_is_not_reported_as_done() -> None:
    with sim("can") as g:
        g.home()
        first_motion(g)
        with held(g, creep=MSG_CREEP_S) as clock:
            handle = g.move(0.09, 0.0025, wait=False)
            step_until(clock, under_way(g, FIRST), "the move under way")
            # what `grippers stop URL` from another shell sends: a 61 with the action bit cleared
            last = g.driver.last_command
            stop = GripperCommand(last.position, 0, 500, activate=True, action=False, estop=False)
            send_raw(g, Cmd.GRIPPER_COMMAND, encode_command(stop))
        with pytest.raises(CommandFailed, match="aborted: the gripper's action bit was cleared"):
            handle.wait(5.0)


@pytest.mark.parametrize("command", [Cmd.IDLE, Cmd.CLEAR_ERROR])
def test_driver_idled_by_another_host_ends_the_wait_as_aborted(command: int) -> None:
    with sim("can") as g:
        g.home()
        first_motion(g)
        with held(g, creep=MSG_CREEP_S) as clock:
            handle = g.move(0.09, 0.0025, wait=False)
            step_until(clock, under_way(g, FIRST), "the move under way")
            send_raw(g, command)  # the 60 frame cannot show the driver mode: the jaws stand still
        with pytest.raises(CommandFailed, match="aborted: the jaws stopped"):
            handle.wait(5.0)


@pytest.mark.parametrize("transport", TRANSPORTS)
def test_grasp_opens_first_when_the_jaws_rest_inside_the_part(transport: str) -> None:
    with sim(transport, part_width_mm=40) as g:
        g.home()  # the jaws rest closed after a calibration
        result = g.grasp(0.04)
        assert result.grasped and result.width == pytest.approx(0.04, abs=0.001)


# ------------------------------------------------------------------------------ model assumed (§4)


def test_info_warns_when_the_model_is_assumed() -> None:
    channel = f"msg-backend-{uuid.uuid4().hex[:8]}"
    with serve_can([MsgModel(node=0)], f"can://virtual/{channel}", time_scale=50.0):
        url = f"stepfoc+can://virtual/{channel}?node=0"
        with grippers.open(url) as g:
            warnings = g.info().extra["warnings"]
            assert any("msg-150 assumed" in w and "pass a profile" in w for w in warnings)
        with grippers.open(url, profile="msg-200") as g:
            assert "warnings" not in g.info().extra


@pytest.mark.parametrize("transport", TRANSPORTS)
def test_stop_from_a_keyboard_interrupt_handler_stops_the_gripper(transport: str) -> None:
    import _thread

    with sim(transport) as g:
        g.home()
        model = g.simulator.model
        for delay in (0.05, 0.11, 0.17):  # Ctrl-C at different moments of the wait loop
            threading.Timer(delay, _thread.interrupt_main).start()
            try:
                g.move(0.09 if model.opening_mm < 45 else 0.0, 0.0025)
            except KeyboardInterrupt:
                g.stop()  # what the base class does before the exception leaves the call
            else:
                pytest.fail("the motion finished before the interrupt")
            with g.simulator.lock if transport == "pty" else threading.Lock():
                at = model.opening_mm
            time.sleep(0.1)
            assert model.opening_mm == pytest.approx(at, abs=0.05)  # stopped, not still travelling
        assert g.move(0.05).width == pytest.approx(0.05, abs=0.001)  # and the link is usable
