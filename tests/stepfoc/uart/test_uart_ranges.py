"""Every number a UART answer carries is checked against its protocol range (issue 13 item 5): a device that
answers ``Gripper current position is: 300`` gives a ProtocolError naming the line, never a width."""

from __future__ import annotations

import pytest

from grippers.drivers.errors import ProtocolError
from grippers.drivers.stepfoc.uart_client import StepfocUart

GRIPINFO = [
    "I am a gripper",
    "Gripper calibrated is: 1",
    "Gripper activated is: 1",
    "Gripper position setpoint is: 10",
    "Gripper speed setpoint is: 20",
    "Gripper current setpoint is: 500",
    "Gripper estop status: 0",
    "Gripper action status: 1",
    "Gripper object detection status: 3",
    "Gripper max open position: -9000",
    "Gripper max closed position: 12000",
]


@pytest.mark.parametrize("value", ["300", "-40", str(10**30), "256"])
def test_position_outside_0_255_is_a_protocol_error(scripted_pty, value: str) -> None:
    pty = scripted_pty(lambda line: f"Gripper current position is: {value}\r\n".encode())
    with StepfocUart(pty.path, timeout=0.5) as client, pytest.raises(ProtocolError) as err:
        client.position()
    assert err.value.command == "Grippos" and err.value.device == pty.path
    text = str(err.value)
    assert f"Gripper current position is: {value}"[:60] in text and "outside 0..255" in text


@pytest.mark.parametrize(
    ("command", "line"),
    [
        ("velocity", "Gripper velocity setpoint is: 999"),
        ("current", "Gripper current setpoint is: 5000"),
        ("current", "Gripper current setpoint is: -1"),
        ("activate", "Gripper activation bit is: 2"),
        ("estop", "Gripper estop bit is: -1"),
        ("gripper", "Gripper: 7"),
    ],
)
def test_single_line_values_outside_their_range(scripted_pty, command: str, line: str) -> None:
    pty = scripted_pty(lambda _line: f"{line}\r\n".encode())
    with StepfocUart(pty.path, timeout=0.5) as client, pytest.raises(ProtocolError, match="outside"):
        getattr(client, command)()


@pytest.mark.parametrize(
    ("index", "bad"),
    [
        (1, "Gripper calibrated is: 2"),
        (3, "Gripper position setpoint is: 300"),
        (4, "Gripper speed setpoint is: -1"),
        (5, "Gripper current setpoint is: 99999"),
        (8, "Gripper object detection status: 4"),
        (9, f"Gripper max open position: {2**40}"),
    ],
)
def test_gripinfo_fields_outside_their_range(scripted_pty, index: int, bad: str) -> None:
    lines = GRIPINFO[:index] + [bad] + GRIPINFO[index + 1 :]
    pty = scripted_pty(lambda _line: "".join(f"{x}\r\n" for x in lines).encode())
    with StepfocUart(pty.path, timeout=0.5) as client, pytest.raises(ProtocolError) as err:
        client.gripinfo()
    assert bad in str(err.value) and err.value.command == "Gripinfo"


def test_info_header_outside_its_range(scripted_pty) -> None:
    info = ["Hardware version: 1", "Batch date: 24", "Software version: 12", "CAN ID is: 99"]

    def script(line: bytes) -> bytes:
        if line.startswith(b"#Info"):
            return "".join(f"{x}\r\n" for x in info).encode()
        return b"Gripper: 1\r\n"

    pty = scripted_pty(script)
    with StepfocUart(pty.path, timeout=0.5) as client, pytest.raises(ProtocolError, match="CAN ID is: 99"):
        client.info()


def test_in_range_values_still_read(scripted_pty) -> None:
    pty = scripted_pty(lambda _line: "".join(f"{x}\r\n" for x in GRIPINFO).encode())
    with StepfocUart(pty.path, timeout=0.5) as client:
        info = client.gripinfo()
    assert info.max_open_position == -9000 and info.current_setpoint == 500
