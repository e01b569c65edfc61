"""The UART client against the pty simulator: the full protocol over a real tty, faults included."""

from __future__ import annotations

import os
import select
import time

import pytest

from grippers.drivers.errors import ConnectionLost, GripperTimeout, NotSupported
from grippers.drivers.stepfoc.can_protocol import Detection
from grippers.drivers.stepfoc.sim.model import MsgModel
from grippers.drivers.stepfoc.uart_client import StepfocUart
from grippers.drivers.stepfoc.uart_protocol import COMMANDS


def wait_for(predicate, timeout: float = 5.0, poll: float = 0.01):
    deadline = time.monotonic() + timeout
    while True:
        value = predicate()
        if value:
            return value
        if time.monotonic() > deadline:
            raise AssertionError("condition not reached")
        time.sleep(poll)


def calibrated_client(srv, **kw) -> StepfocUart:
    client = StepfocUart(srv.url, timeout=kw.pop("timeout", 2.0), **kw)
    client.calibrate(wait=True, timeout=10)
    return client


def test_url_and_attributes(msg_sim) -> None:
    srv = msg_sim()
    assert srv.url.startswith("stepfoc+serial:///dev/pts/")
    assert srv.models == [srv.model] and isinstance(srv.model, MsgModel)
    assert srv.clock.time_scale == 200.0


def test_calibrate_move_and_read(msg_sim) -> None:
    srv = msg_sim()
    with StepfocUart(srv.url, timeout=2.0) as client:
        assert client.gripper() == 1
        assert not client.gripinfo().calibrated
        client.calibrate(wait=True, timeout=10)
        info = client.gripinfo()
        assert (
            info.calibrated and info.max_open_position > info.max_closed_position
        )  # ticks grow towards open
        # calibration leaves the jaws at the closed stop (docs/protocols.md §2)
        assert client.position() == 255
        assert client.velocity(255) == 255
        assert client.current(800) == 800
        client.position(128)
        info = wait_for(lambda: (i := client.gripinfo()).detection is Detection.AT_POSITION and i)
        assert info.activated and info.action and info.position_setpoint == 128
        assert client.position() in (127, 128)  # integer truncation (docs/protocols.md §2)
        client.position(0)
        wait_for(lambda: client.position() == 0)


def test_closing_on_a_part_reports_detection_1(msg_sim) -> None:
    srv = msg_sim(MsgModel(part_width_mm=50.0))
    with calibrated_client(srv) as client:
        client.velocity(255)
        client.current(500)
        client.position(0)
        wait_for(lambda: client.gripinfo().detection is Detection.AT_POSITION)
        client.position(255)
        info = wait_for(lambda: (i := client.gripinfo()).detection is not Detection.MOVING and i)
        assert info.detection is Detection.CLOSING_OBJECT
        assert 0 < client.position() < 255


def test_uncalibrated_gripper_does_not_move(msg_sim) -> None:
    srv = msg_sim()
    with StepfocUart(srv.url, timeout=2.0) as client:
        client.velocity(255)
        before = srv.model.ticks
        client.position(10)
        time.sleep(0.05)
        assert srv.model.ticks == before
        assert client.gripinfo().activated  # Grippos N activates even so (docs/protocols.md §2)


def test_estop_and_clear(msg_sim) -> None:
    srv = msg_sim()
    with calibrated_client(srv) as client:
        client.velocity(10)
        client.current(600)
        client.position(0)
        assert client.estop(1) == 1
        assert srv.model.estop_error
        stopped_at = client.position()
        time.sleep(0.05)
        assert client.position() == stopped_at
        assert client.gripinfo().estop
        assert client.estop(0) == 0
        assert srv.model.estop_error  # the bit alone does not clear the error
        client.clear_error()
        assert not srv.model.estop_error and not client.gripinfo().estop


def test_info(msg_sim) -> None:
    srv = msg_sim(MsgModel(node=5, hardware_version=3, software_version=17, batch_date=9))
    with StepfocUart(srv.url, timeout=2.0) as client:
        info = client.info()
    assert (info.hardware_version, info.batch_date, info.software_version, info.can_id) == (3, 9, 17, 5)
    assert info.vbus_mv == srv.model.bus_voltage_mv and info.thermistor_enabled is False
    assert info.unknown_lines == ()


def test_gripper_mode_flag(msg_sim) -> None:
    srv = msg_sim()
    with StepfocUart(srv.url, timeout=2.0) as client:
        assert client.gripper(0) == 0
        assert client.gripinfo().is_gripper is False
        assert client.gripper(1) == 1


def test_unknown_command_answer(msg_sim) -> None:
    srv = msg_sim()
    with StepfocUart(srv.url, timeout=2.0) as client:
        with pytest.raises(NotSupported) as err:
            client.command("SIN", 3)  # the parser knows SIN, communication.cpp does not: "Unknown command"
        assert err.value.command == "SIN" and "Unknown command" in str(err.value)
        assert client.command("Gripvel") == "Gripper velocity setpoint is: 0"


def test_unknown_command_silence_times_out(msg_sim) -> None:
    srv = msg_sim(unknown_reply=None)
    with StepfocUart(srv.url, timeout=0.2) as client, pytest.raises(GripperTimeout) as err:
        client.command("Nosuchthing")
    assert err.value.command == "Nosuchthing"
    assert srv.requests[-1].name == "Nosuchthing"


def test_silent_device_times_out_then_recovers(msg_sim) -> None:
    srv = msg_sim()
    with StepfocUart(srv.url, timeout=0.2) as client:
        srv.faults.silent = True
        with pytest.raises(GripperTimeout):
            client.gripinfo()
        srv.faults.silent = False
        assert client.gripper() == 1


def test_garbage_and_corruption_resynchronise(msg_sim) -> None:
    srv = msg_sim()
    with StepfocUart(srv.url, timeout=2.0) as client:
        srv.faults.send_garbage(b"\x00\xff#garbage\r\nGripper: 9\r\nnot a line" + b"x" * 600 + b"\n")
        assert client.velocity(33) == 33
        srv.faults.send_garbage(b"\xfe\xfe\r\n")
        assert client.gripinfo().speed_setpoint == 33
        srv.faults.corrupt_replies(1)
        with pytest.raises(GripperTimeout):
            client.velocity()  # the corrupted answer is refused, not misread
        srv.faults.truncate_replies(1)
        with pytest.raises(GripperTimeout):
            client.gripinfo()  # half a record is never returned
        assert client.gripinfo().speed_setpoint == 33
        assert client.discarded > 0


def test_dropped_and_late_answers(msg_sim) -> None:
    srv = msg_sim()
    # An exchange timeout of 1 s (not 0.2 s: a simulator starved of the CPU on a busy machine answered late
    # and failed the last, undelayed exchange), the late answer 0.5 s after it.
    with StepfocUart(srv.url, timeout=1.0) as client:
        srv.faults.drop_replies(1)
        with pytest.raises(GripperTimeout):
            client.velocity(40)
        assert srv.model.speed_setpoint == 40  # the command arrived; only the answer was lost
        srv.faults.delay_replies(1.5, 1)
        with pytest.raises(GripperTimeout):
            client.current(300)
        time.sleep(0.6)  # the late answer arrives now, and must not answer the next command
        assert client.velocity() == 40


def test_hash_resets_receiver_and_no_echo(msg_sim) -> None:
    srv = msg_sim()
    with StepfocUart(srv.url, timeout=2.0) as client:
        client._ser.write(b"#Gripvel 12")  # never finished ...
        assert client.velocity(77) == 77  # ... '#' starts over
        assert srv.requests[-1].argument == "77"
        client._ser.reset_input_buffer()
        client._ser.write(b"#Gripvel\n")
        data = b""
        deadline = time.monotonic() + 2
        while not data.endswith(b"\r\n") and time.monotonic() < deadline:
            data += client._ser.read(64)
        assert data == COMMANDS["Gripvel"].render(77).encode() + b"\r\n"  # the answer only, no echo


def test_server_close_makes_the_port_disappear(msg_sim) -> None:
    srv = msg_sim()
    client = StepfocUart(srv.url, timeout=0.3)
    assert client.gripper() == 1
    srv.close()
    srv.close()
    with pytest.raises(ConnectionLost):
        client.gripper()
    client.close()


def test_request_close_fault(msg_sim) -> None:
    srv = msg_sim()
    with StepfocUart(srv.url, timeout=0.3) as client:
        srv.faults.request_close()
        with pytest.raises(ConnectionLost):
            wait_for(lambda: client.gripper() and False, timeout=2)


def test_close_releases_thread_and_fds(msg_sim) -> None:
    srv = msg_sim()
    master = srv._master
    srv.close()
    assert not srv._thread.is_alive()
    with pytest.raises(OSError):
        os.fstat(master)


def test_raw_pty_exchange_with_cr_lf(msg_sim) -> None:
    """A terminal program sending CR LF gets the same answer (docs/protocols.md §2: '\\r\\n works')."""
    srv = msg_sim()
    fd = os.open(srv.path, os.O_RDWR | os.O_NOCTTY)
    try:
        os.write(fd, b"#Gripcur 650\r\n")
        data = b""
        deadline = time.monotonic() + 2
        while b"\n" not in data and time.monotonic() < deadline:
            if select.select([fd], [], [], 0.05)[0]:
                data += os.read(fd, 100)
        assert data == b"Gripper current setpoint is: 650\r\n"
    finally:
        os.close(fd)


def test_serve_uart_arguments() -> None:
    from grippers.drivers.stepfoc.sim.uart_server import serve_uart

    with pytest.raises(ValueError):
        serve_uart(MsgModel(), "tcp://127.0.0.1:0")
    with pytest.raises(ValueError):
        serve_uart([MsgModel(), MsgModel(node=1)])
    with serve_uart([MsgModel()], time_scale=50) as srv:
        assert srv.clock.time_scale == 50


def test_package_serve_dispatches_pty() -> None:
    from grippers.drivers.stepfoc.sim import serve

    with serve(MsgModel(), "pty", time_scale=100.0) as srv, StepfocUart(srv.url, timeout=2.0) as client:
        assert client.gripper() == 1
