"""StepfocUart against a pty whose far end answers with exact firmware lines written by hand.

These pin the client to the wire text of docs/protocols.md §2 independently of our simulator.
"""

from __future__ import annotations

import threading

import pytest

from grippers.drivers.errors import ConnectionLost, GripperTimeout, LimitError, NotSupported, ProtocolError
from grippers.drivers.stepfoc.can_protocol import Detection
from grippers.drivers.stepfoc.uart_client import StepfocUart

GRIPINFO = (
    b"I am a gripper\r\n"
    b"Gripper calibrated is: 1\r\n"
    b"Gripper activated is: 1\r\n"
    b"Gripper position setpoint is: 128\r\n"
    b"Gripper speed setpoint is: 200\r\n"
    b"Gripper current setpoint is: 700\r\n"
    b"Gripper estop status: 0\r\n"
    b"Gripper action status: 1\r\n"
    b"Gripper object detection status: 3\r\n"
    b"Gripper max open position: -10500\r\n"
    b"Gripper max closed position: 10500\r\n"
)
INFO = (
    b"Hardware version: 2\r\nBatch date: 23\r\nSoftware version: 14\r\nCAN ID is: 3\r\n"
    b"Calibrated\r\nTermistor is disabled\r\nVbus voltage: 23950 mV\r\nPhase direction: 1\r\n"
    b"Phase Order: 0\r\nNumber of pole pairs: 7\r\nSingle phase resistance: 0.51000\r\n"
    b"Single phase Inductance: 0.00030\r\nKt: 0.04000\r\nKV: 200.00000\r\nSomething new: 42\r\n"
)

FIRMWARE = {
    b"#Gripper\n": b"Gripper: 1\r\n",
    b"#Gripper 0\n": b"Gripper: 0\r\n",
    b"#Gripcal\n": b"Gripper calibration! \r\n",
    b"#Grippos\n": b"Gripper current position is: 254\r\n",
    b"#Grippos 128\n": b"Gripper current position is: 255\r\n",
    b"#Gripvel 200\n": b"Gripper velocity setpoint is: 200\r\n",
    b"#Gripcur 700\n": b"Gripper current setpoint is: 700\r\n",
    b"#Gripcur\n": b"Gripper current setpoint is: 700\r\n",
    b"#Gripact 1\n": b"Gripper activation bit is: 1\r\n",
    b"#Gripstop 1\n": b"Gripper estop bit is: 1\r\n",
    b"#Clear\n": b"Clear errors\r\n",
    b"#Gripinfo\n": GRIPINFO,
    b"#Info\n": INFO,
}


def firmware(line: bytes) -> bytes | None:
    return FIRMWARE.get(line)


@pytest.fixture
def uart(scripted_pty):
    pty = scripted_pty(firmware)
    client = StepfocUart(pty.path, timeout=0.3)
    yield client, pty
    client.close()


def test_every_command_exact_bytes(uart) -> None:
    client, pty = uart
    assert client.gripper() == 1
    assert client.gripper(False) == 0
    client.calibrate()
    assert client.position() == 254
    assert client.position(128) == 255  # the actual position, not the setpoint
    assert client.velocity(200) == 200
    assert client.current(700) == 700
    assert client.activate(True) == 1
    assert client.estop(1) == 1
    client.clear_error()
    assert pty.received == [
        b"#Gripper\n",
        b"#Gripper 0\n",
        b"#Gripcal\n",
        b"#Grippos\n",
        b"#Grippos 128\n",
        b"#Gripvel 200\n",
        b"#Gripcur 700\n",
        b"#Gripact 1\n",
        b"#Gripstop 1\n",
        b"#Clear\n",
    ]


def test_gripinfo_record(uart) -> None:
    client, _ = uart
    info = client.gripinfo()
    assert info.is_gripper and info.calibrated and info.activated and info.action and not info.estop
    assert (info.position_setpoint, info.speed_setpoint, info.current_setpoint) == (128, 200, 700)
    assert info.detection is Detection.AT_POSITION
    assert (info.max_open_position, info.max_closed_position) == (-10500, 10500)


def test_info_record_with_unknown_status_line(uart) -> None:
    client, pty = uart
    info = client.info()
    assert (info.hardware_version, info.batch_date, info.software_version, info.can_id) == (2, 23, 14, 3)
    assert info.vbus_mv == 23950 and info.pole_pairs == 7 and info.kv == pytest.approx(200.0)
    assert info.calibrated is True and info.thermistor_enabled is False
    assert info.unknown_lines == ("Something new: 42",)
    assert pty.received[-2:] == [b"#Info\n", b"#Gripper\n"]  # the end marker behind Info


def test_current_is_clamped_to_the_profile_limit(scripted_pty) -> None:
    pty = scripted_pty(firmware)
    with StepfocUart(pty.path, timeout=0.3, current_limit_ma=700) as client:
        assert client.current(2500) == 700
    assert pty.received == [b"#Gripcur 700\n"]


@pytest.mark.parametrize(
    ("method", "value"),
    [
        ("position", 256),
        ("position", -1),
        ("velocity", 300),
        ("activate", 2),
        ("estop", -1),
        ("gripper", 3),
        ("current", -5),
        ("position", 1.5),
        ("velocity", True),
    ],
)
def test_out_of_range_refused_before_sending(uart, method: str, value: object) -> None:
    client, pty = uart
    with pytest.raises(LimitError) as err:
        getattr(client, method)(value)
    assert err.value.device == pty.path and err.value.command
    client.gripper()  # the port is still in step
    assert pty.received == [b"#Gripper\n"]


def test_unknown_command_answer_is_a_clear_error(scripted_pty) -> None:
    pty = scripted_pty(lambda line: b"Unknown command\r\n")
    with StepfocUart(pty.path, timeout=0.3) as client, pytest.raises(NotSupported) as err:
        client.gripinfo()
    assert "Unknown command" in str(err.value) and err.value.command == "Gripinfo"
    assert pty.path in str(err.value)


def test_silence_times_out_naming_port_and_command(scripted_pty) -> None:
    pty = scripted_pty(lambda line: None)  # the firmware ignores names it does not know
    with StepfocUart(pty.path, timeout=0.2) as client:
        with pytest.raises(GripperTimeout) as err:
            client.position()
        assert isinstance(err.value, TimeoutError)
        assert err.value.command == "Grippos" and err.value.device == pty.path


def test_garbage_before_and_between_answers(scripted_pty) -> None:
    noise = b"\xff\xfe\x00junk\r\nGripper: 1\r\n$ 1 2 3 \r\n" + b"z" * 400 + b"\r\n"

    def noisy(line: bytes) -> bytes | None:
        answer = FIRMWARE.get(line)
        if line == b"#Gripinfo\n":
            # a stray line in the middle of a record: the half record is thrown away, the next full one taken
            return noise + GRIPINFO[:60] + b"oops\r\n" + GRIPINFO
        return None if answer is None else noise + answer

    pty = scripted_pty(noisy)
    with StepfocUart(pty.path, timeout=0.5, max_line=128) as client:
        assert client.position() == 254  # 'Gripper: 1' is not Grippos's answer and is skipped
        assert client.gripinfo().detection is Detection.AT_POSITION
        assert client.info().can_id == 3
        assert client.discarded > 0


def test_endless_garbage_is_bounded(scripted_pty) -> None:
    pty = scripted_pty(lambda line: b"noise\r\n" * 50)
    with StepfocUart(pty.path, timeout=2.0, max_discard=20) as client, pytest.raises(ProtocolError):
        client.velocity()


def test_stale_input_flushed_before_a_command(scripted_pty) -> None:
    pty = scripted_pty(firmware)
    with StepfocUart(pty.path, timeout=0.3) as client:
        pty.write(b"Gripper current position is: 7\r\n")  # a late answer from before
        import time

        time.sleep(0.05)
        assert client.position() == 254


def test_answer_split_over_many_writes(scripted_pty) -> None:
    pty_holder = {}

    def slow(line: bytes) -> None:
        def dribble() -> None:
            for i in range(len(GRIPINFO)):
                pty_holder["p"].write(GRIPINFO[i : i + 1])

        threading.Thread(target=dribble, daemon=True).start()
        return None

    pty = scripted_pty(slow)
    pty_holder["p"] = pty
    with StepfocUart(pty.path, timeout=1.0) as client:
        assert client.gripinfo().max_closed_position == 10500


def test_threads_do_not_steal_answers(uart) -> None:
    client, _ = uart
    errors: list[BaseException] = []

    def worker(fn, expected) -> None:
        try:
            for _ in range(15):
                assert fn() == expected
        except BaseException as exc:  # noqa: BLE001 - collected for the main thread
            errors.append(exc)

    threads = [
        threading.Thread(target=worker, args=(client.position, 254)),
        threading.Thread(target=worker, args=(client.gripper, 1)),
        threading.Thread(target=worker, args=(lambda: client.gripinfo().speed_setpoint, 200)),
    ]
    for t in threads:
        t.start()
    for t in threads:
        t.join(20)
    assert not errors


def test_port_that_disappears(scripted_pty) -> None:
    pty = scripted_pty(firmware)
    client = StepfocUart(pty.path, timeout=0.3)
    assert client.gripper() == 1
    pty.close_master()
    with pytest.raises(ConnectionLost) as err:
        client.gripper()
    assert isinstance(err.value, ConnectionError) and err.value.device == pty.path
    client.close()
    client.close()


def test_close_is_idempotent_and_final(uart) -> None:
    client, _ = uart
    with client:
        pass
    assert client.closed
    client.close()
    with pytest.raises(ConnectionLost):
        client.gripper()


def test_open_failure_is_connection_lost() -> None:
    with pytest.raises(ConnectionLost):
        StepfocUart("/dev/does-not-exist-grippers")


def test_loop_url_and_family_prefix(scripted_pty) -> None:
    pty = scripted_pty(firmware)
    with StepfocUart(f"stepfoc+serial://{pty.path}", timeout=0.3) as client:
        assert client.port == pty.path and client.gripper() == 1
    # pyserial URLs work too: loop:// echoes the command back, which is not an answer
    with StepfocUart("loop://", timeout=0.1) as client, pytest.raises(GripperTimeout):
        client.gripper()
