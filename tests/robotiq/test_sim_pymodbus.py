"""The simulator driven by pymodbus, an independent Modbus client, over the pty (the RTU line) and over TCP
carrying raw RTU frames (a UR forwarder), through the manual's sequence: activation, close, status reads."""

from __future__ import annotations

from collections.abc import Iterator
from typing import Any

import pytest
from pymodbus import FramerType
from pymodbus.client import ModbusSerialClient, ModbusTcpClient
from pymodbus.exceptions import ModbusIOException

from grippers.drivers.robotiq.registers import (
    COMMAND_ADDRESS,
    STATUS_ADDRESS,
    ActivationState,
    Command,
    Status,
)
from grippers.drivers.robotiq.sim import RobotiqModel, RobotiqSimServer, serve
from tests.pymodbus_peer import unit


def _kw(slave: int = 9) -> dict[str, Any]:
    return unit(slave)


@pytest.fixture(params=["pty", "tcp"])
def peer(request: pytest.FixtureRequest) -> Iterator[tuple[RobotiqSimServer, Any]]:
    server = serve(RobotiqModel(), "pty" if request.param == "pty" else "tcp://127.0.0.1:0", time_scale=1.0)
    client: Any
    if request.param == "pty":
        client = ModbusSerialClient(server.path, baudrate=115200, timeout=2, retries=0)
    else:
        client = ModbusTcpClient("127.0.0.1", port=server.port, framer=FramerType.RTU, timeout=2, retries=0)
    assert client.connect()
    try:
        yield server, client
    finally:
        client.close()
        server.close()
        assert server.error is None


def _status(client: Any, function: str = "read_holding_registers") -> Status:
    rr = getattr(client, function)(STATUS_ADDRESS, count=3, **_kw())
    assert not rr.isError(), rr
    return Status.from_registers(rr.registers)


def test_the_manual_s_activation_and_grip_sequence(peer: tuple[RobotiqSimServer, Any]) -> None:
    server, client = peer
    server.pause()  # the sweep is held still while we look at it
    assert not client.write_registers(COMMAND_ADDRESS, list(Command().registers()), **_kw()).isError()
    assert not client.write_registers(COMMAND_ADDRESS, list(Command(act=True).registers()), **_kw()).isError()
    st = _status(client, "read_input_registers")
    assert st.act and st.sta == ActivationState.IN_PROGRESS
    server.step(1.5)
    assert _status(client).activated
    with server.lock:
        server.model.part_width_mm = 40.0
    close = Command(act=True, gto=True, position=255, speed=255, force=255)
    assert not client.write_registers(COMMAND_ADDRESS, list(close.registers()), **_kw()).isError()
    st = _status(client)
    assert st.moving and st.position_echo == 255 and st.current_ma == 160
    server.step(2.0)
    st = _status(client, "read_input_registers")
    assert st.obj == 2 and not st.moving and abs(server.model.width_mm() - 40.0) < 0.5


def test_read_write_in_one_exchange_as_the_sdk_cycles(peer: tuple[RobotiqSimServer, Any]) -> None:
    server, client = peer
    server.pause()
    rr = client.readwrite_registers(
        read_address=STATUS_ADDRESS,
        read_count=3,
        write_address=COMMAND_ADDRESS,
        values=list(Command(act=True).registers()),
        **_kw(),
    )
    assert not rr.isError()
    assert Status.from_registers(rr.registers).sta == ActivationState.IN_PROGRESS


def test_another_slave_id_gets_no_answer_and_a_bad_address_an_exception(
    peer: tuple[RobotiqSimServer, Any],
) -> None:
    server, client = peer
    rr = client.read_holding_registers(0x0100, count=3, **_kw())
    assert rr.isError() and rr.exception_code == 2
    with pytest.raises(ModbusIOException):
        client.read_holding_registers(STATUS_ADDRESS, count=3, **_kw(10))
    assert server.model.requests == 1  # the request for slave 10 was neither answered nor counted
