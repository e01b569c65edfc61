"""The Robotiq family on the kit's Modbus part: an exception reply reaches the user as the kit's
typed error through the whole stack, and the Robotiq register model serves Modbus TCP as well (a gripper
behind a Modbus TCP gateway), with pymodbus as the independent peer."""

from __future__ import annotations

import pytest
from pymodbus import FramerType
from pymodbus.client import ModbusTcpClient

import grippers
from grippers import CommandFailed
from grippers.drivers.robotiq.client import RobotiqClient
from grippers.drivers.robotiq.registers import (
    COMMAND_ADDRESS,
    STATUS_ADDRESS,
    ActivationState,
    Command,
    Status,
)
from grippers.drivers.robotiq.sim import RobotiqModel
from grippers.kit import ModbusFaults, ModbusSimServer, ServerDeviceBusy
from tests.pymodbus_peer import unit


@pytest.mark.parametrize("transport", ["tcp", "pty"])
def test_an_exception_reply_is_the_kit_s_typed_error_naming_the_gripper(transport: str) -> None:
    with grippers.open(f"sim://robotiq-2f85?transport={transport}&activated=true") as g:
        assert isinstance(g.simulator.faults, ModbusFaults)
        g.simulator.faults.exception_replies(6)
        with pytest.raises(ServerDeviceBusy) as caught:
            g.state()
        err = caught.value
        assert isinstance(err, CommandFailed) and err.status == 6 and err.command == "state"
        assert err.device == g.simulator.url and "server_device_busy" in str(err)
        assert g.state().width > 0  # the next exchange is answered


def test_the_robotiq_model_behind_a_modbus_tcp_gateway() -> None:
    server = ModbusSimServer(RobotiqModel(), "tcp://127.0.0.1:0", framing="tcp", family="robotiq")
    server.pause()
    peer = ModbusTcpClient("127.0.0.1", port=server.port, framer=FramerType.SOCKET, timeout=2, retries=0)
    client = RobotiqClient.tcp("127.0.0.1", int(server.port or 0), framing="tcp", device="gateway", timeout=2)
    try:
        client.write_command(Command(act=True))
        assert client.read_status().sta == ActivationState.IN_PROGRESS
        server.step(1.5)
        assert peer.connect()
        rr = peer.read_holding_registers(STATUS_ADDRESS, count=3, **unit(9))
        assert not rr.isError() and Status.from_registers(rr.registers).activated
        close = Command(act=True, gto=True, position=255, speed=255, force=255)
        assert not peer.write_registers(COMMAND_ADDRESS, list(close.registers()), **unit(9)).isError()
        assert client.write_and_read(close).position_echo == 255
    finally:
        peer.close()
        client.close()
        server.close()
    assert server.error is None
