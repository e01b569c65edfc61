"""The kit's Modbus part against an independent peer, pymodbus, both ways: pymodbus's clients ask the kit's
register-model simulator (RTU on a pty, RTU over TCP, Modbus TCP), the kit's client asks pymodbus's server
(Modbus TCP). Then the faults a real line has, as the kit's client sees them, and the typed errors."""

from __future__ import annotations

import asyncio
import contextlib
import inspect
import socket
import threading
import time
from collections.abc import Iterator
from typing import Any

import pytest
from pymodbus import FramerType
from pymodbus.client import ModbusSerialClient, ModbusTcpClient
from pymodbus.exceptions import ModbusIOException

from grippers import CommandFailed, ConnectionLost, GripperTimeout, ProtocolError
from grippers.kit import (
    FaultHooks,
    IllegalDataAddress,
    IllegalFunction,
    ModbusClient,
    ModbusException,
    ModbusFaults,
    ModbusLengthError,
    ModbusSimServer,
    ModbusUnitError,
    RegisterMap,
    RegisterModel,
    ServerDeviceBusy,
    SimClock,
)
from tests.pymodbus_peer import unit
from tests.scripted_peer import scripted_peer

LISTEN = {"pty": "pty", "rtu-over-tcp": "tcp://127.0.0.1:0", "modbus-tcp": "tcp://127.0.0.1:0"}


def _map(slave: int = 7) -> RegisterMap:
    return RegisterMap(
        slave, holding={a: a * 10 for a in range(100, 110)}, inputs={0: 0xBEEF, 1: 1}, read_only=[109]
    )


def _serve(kind: str, model: RegisterModel, **kw: Any) -> ModbusSimServer:
    return ModbusSimServer(model, LISTEN[kind], framing="tcp" if kind == "modbus-tcp" else "rtu", **kw)


def _pymodbus_client(kind: str, server: ModbusSimServer) -> Any:
    if kind == "pty":
        return ModbusSerialClient(server.path, baudrate=115200, timeout=2, retries=0)
    framer = FramerType.SOCKET if kind == "modbus-tcp" else FramerType.RTU
    return ModbusTcpClient("127.0.0.1", port=server.port, framer=framer, timeout=2, retries=0)


def _client(kind: str, server: ModbusSimServer, slave: int = 7, timeout: float = 2.0) -> ModbusClient:
    if kind == "pty":
        return ModbusClient.serial(str(server.path), slave=slave, timeout=timeout, device="sim")
    framing = "tcp" if kind == "modbus-tcp" else "rtu"
    return ModbusClient.tcp("127.0.0.1", int(server.port or 0), framing=framing, slave=slave, timeout=timeout)


@pytest.fixture(params=list(LISTEN))
def kind(request: pytest.FixtureRequest) -> str:
    return str(request.param)


# -- pymodbus asks the kit's simulator -----------------------------------------------------------------------


def test_pymodbus_reads_writes_and_is_refused_by_the_register_map(kind: str) -> None:
    model = _map()
    server = _serve(kind, model)
    client = _pymodbus_client(kind, server)
    try:
        assert client.connect()
        rr = client.read_holding_registers(100, count=3, **unit(7))
        assert not rr.isError() and rr.registers == [1000, 1010, 1020]
        assert client.read_input_registers(0, count=2, **unit(7)).registers == [0xBEEF, 1]
        assert not client.write_registers(101, [1, 2], **unit(7)).isError()
        assert model.holding[101] == 1 and model.holding[102] == 2
        rw = client.readwrite_registers(
            read_address=100, read_count=3, write_address=100, values=[5], **unit(7)
        )
        assert rw.registers == [5, 1, 2]  # written first (application protocol V1.1b3 §6.17)
        assert client.read_holding_registers(200, count=1, **unit(7)).exception_code == 2
        assert client.write_registers(109, [1], **unit(7)).exception_code == 2  # read-only
        assert isinstance(server.faults, ModbusFaults)
        server.faults.exception_replies(6)
        assert client.read_holding_registers(100, count=1, **unit(7)).exception_code == 6
        if kind != "modbus-tcp":  # RTU: another id on the line is never answered
            with pytest.raises(ModbusIOException):
                client.read_holding_registers(100, count=1, **unit(8))
    finally:
        client.close()
        server.close()
    assert server.error is None


# -- the kit's client asks pymodbus's server (Modbus TCP) ----------------------------------------------------


@contextlib.contextmanager
def _pymodbus_server(slave: int) -> Iterator[int]:
    from pymodbus import datastore
    from pymodbus.server import ModbusTcpServer

    # pymodbus's blocks start one register early (its "address - 1"): register 0 is values[0] from 1.
    block = datastore.ModbusSequentialDataBlock
    device_cls = getattr(datastore, "ModbusDeviceContext", None) or datastore.ModbusSlaveContext
    device = device_cls(hr=block(1, list(range(200))), ir=block(1, [7] * 10))
    key = "devices" if "devices" in inspect.signature(datastore.ModbusServerContext).parameters else "slaves"
    context = datastore.ModbusServerContext(**{key: {slave: device}}, single=False)
    with socket.socket() as probe:
        probe.bind(("127.0.0.1", 0))
        port = probe.getsockname()[1]
    loop = asyncio.new_event_loop()
    servers: list[Any] = []

    async def serve() -> None:  # pymodbus's server is made inside its running loop
        servers.append(ModbusTcpServer(context, framer=FramerType.SOCKET, address=("127.0.0.1", port)))
        await servers[0].serve_forever()

    thread = threading.Thread(target=loop.run_until_complete, args=(serve(),), daemon=True)
    thread.start()
    try:
        deadline = time.monotonic() + 10
        while True:
            with socket.socket() as s:
                if s.connect_ex(("127.0.0.1", port)) == 0:
                    break
            assert time.monotonic() < deadline, "pymodbus's server did not start"
            time.sleep(0.02)
        yield port
    finally:
        asyncio.run_coroutine_threadsafe(servers[0].shutdown(), loop).result(10)
        thread.join(10)


def test_the_client_against_pymodbus_s_server() -> None:
    with _pymodbus_server(5) as port, ModbusClient.tcp("127.0.0.1", port, slave=5, timeout=2) as client:
        assert client.read_holding_registers(10, 3) == (10, 11, 12)
        assert client.read_input_registers(0, 2) == (7, 7)
        client.write_registers(10, [1, 2, 3])
        assert client.read_holding_registers(10, 3) == (1, 2, 3)
        assert client.read_write_registers(20, 2, 20, [9, 8]) == (9, 8)
        with pytest.raises(IllegalDataAddress) as caught:
            client.read_holding_registers(190, 20, command="status")
        err = caught.value
        assert (
            isinstance(err, CommandFailed) and err.status == 2 and err.status_name == "illegal_data_address"
        )
        assert err.device == f"127.0.0.1:{port}" and err.command == "status" and err.function == 3
        assert client.read_holding_registers(10, 1) == (1,)  # the line stays in step


# -- the kit's client and simulator: faults, clock, typed errors ---------------------------------------------


def test_the_client_over_every_framing_and_a_refusal_names_device_command_and_cause(kind: str) -> None:
    server = _serve(kind, _map())
    client = _client(kind, server)
    try:
        assert client.read_holding_registers(100, 2) == (1000, 1010)
        client.write_registers(100, [1, 2])
        assert client.read_write_registers(100, 2, 102, [3]) == (1, 2)
        assert isinstance(server.faults, ModbusFaults)
        server.faults.exception_replies(6, 1)
        with pytest.raises(ServerDeviceBusy, match=r"sim|127\.0\.0\.1") as caught:
            client.read_holding_registers(100, 1, command="state")
        assert caught.value.command == "state" and "server_device_busy" in str(caught.value)
        with pytest.raises(IllegalDataAddress, match="to write multiple registers"):
            client.write_registers(109, [0])
        with pytest.raises(ValueError):
            client.read_holding_registers(100, 126)  # no frame holds it: refused before sending
        assert client.exchanges == 5
    finally:
        client.close()
        server.close()


def test_a_late_reply_is_never_the_next_one_s(kind: str) -> None:
    model = _map()
    server = _serve(kind, model)
    client = _client(kind, server, timeout=0.3)
    try:
        server.faults.delay_replies(0.6)
        with pytest.raises(GripperTimeout, match="no answer from slave 7"):
            client.read_holding_registers(100, 1)
        deadline = time.monotonic() + 10
        while server._delayed:  # the kit's server: until the late reply is on its way
            assert time.monotonic() < deadline
            time.sleep(0.01)
        time.sleep(0.2)
        with server.lock:
            model.holding[100] = 4242
        client.timeout = 5.0  # a value from here, not a time: a starved simulator overran 0.3 s (CI N16)
        assert client.read_holding_registers(100, 1) == (4242,)  # not the late 1000
    finally:
        client.close()
        server.close()


def test_corrupt_and_other_slave_replies_say_why_the_exchange_timed_out() -> None:
    server = _serve("pty", _map(slave=7))
    try:
        with _client("pty", server, timeout=0.3) as client:
            server.faults.corrupt_replies(1)
            with pytest.raises(GripperTimeout, match="dropped: bad CRC") as caught:
                client.read_holding_registers(100, 1)
            assert isinstance(caught.value.__cause__, ProtocolError)
            client.timeout = 5.0  # values from here, not times (a starved simulator)
            server.faults.send_garbage(b"\x07\x03\x02\xff")  # a false header: resynchronised
            assert client.read_holding_registers(100, 1) == (1000,)
        with (
            _client("pty", server, slave=8, timeout=0.3) as other,
            pytest.raises(GripperTimeout, match=r"no answer from slave 8 within 0.3 s$"),
        ):
            other.read_holding_registers(100, 1)  # slave 7 stays silent: nothing to say but that
    finally:
        server.close()


def test_a_lost_link_is_connection_lost_for_the_exchange_and_after() -> None:
    server = _serve("modbus-tcp", _map())
    client = _client("modbus-tcp", server, timeout=1.0)
    try:
        assert client.read_holding_registers(100, 1) == (1000,)
        server.faults.request_close()
        with pytest.raises(ConnectionLost):
            for _ in range(50):  # the close lands between two exchanges
                client.read_holding_registers(100, 1)
                time.sleep(0.02)
        assert client.lost and not client.alive
        with pytest.raises(ConnectionLost, match="the link is down"):
            client.read_holding_registers(100, 1)
    finally:
        client.close()
        server.close()


def test_clock_and_faults_given_at_construction_hold_from_the_first_request() -> None:
    class Ticking(RegisterModel):
        """Register 0 counts simulated tenths of a second."""

        slave = 1
        functions = frozenset({3})

        def __init__(self) -> None:
            self.t = 0.0

        def advance(self, now: float) -> None:
            self.t = now

        def read(self, function: int, address: int, count: int, now: float) -> list[int]:
            if address != 0 or count != 1:
                raise IllegalDataAddress()
            return [round(now * 10)]

    faults = ModbusFaults()
    faults.exception_replies(4)
    faults.delay_replies(0.1)
    clock = SimClock(100.0, paused=True)
    server = ModbusSimServer(Ticking(), "tcp://127.0.0.1:0", clock=clock, faults=faults)
    assert server.clock is clock and server.faults is faults
    try:
        with ModbusClient.tcp("127.0.0.1", int(server.port or 0), framing="rtu", slave=1, timeout=2) as c:
            with pytest.raises(ModbusException) as caught:  # 04 has a class: ServerDeviceFailure
                c.read_holding_registers(0, 1)
            assert caught.value.status == 4
            time.sleep(0.2)  # at a time scale of 100, 20 simulated seconds if the clock ran
            assert c.read_holding_registers(0, 1) == (0,)
            server.step(0.5)
            assert c.read_holding_registers(0, 1) == (5,)
            with pytest.raises(IllegalFunction):
                c.read_write_registers(0, 1, 0, [1])  # a function the model does not list
    finally:
        server.close()


def test_a_plain_fault_hooks_object_is_taken_too() -> None:
    hooks = FaultHooks()
    hooks.silent = True
    server = ModbusSimServer(_map(), "pty", faults=hooks)
    try:
        with _client("pty", server, timeout=0.2) as c:
            with pytest.raises(GripperTimeout):
                c.read_holding_registers(100, 1)
            hooks.silent = False
            c.timeout = 5.0  # a value from here, not a time (a starved simulator)
            assert c.read_holding_registers(100, 1) == (1000,)
    finally:
        server.close()


def test_modbus_tcp_frames_that_lie_are_typed_errors_and_the_line_recovers() -> None:
    """A scripted device: a reply from another unit id, then a header that is not Modbus's."""
    from grippers.drivers.modbus_tcp import mbap_frame

    answers = iter(["unit", "header", "good"])

    def answer(request: bytes) -> bytes:
        tid = int.from_bytes(request[:2], "big")
        what = next(answers)
        if what == "unit":
            return mbap_frame(tid, 9, bytes([3, 2, 0, 1]))
        if what == "header":
            return b"\x00\x01\x00\x07\x00\x05\x01garbage"
        return mbap_frame(tid, 5, bytes([3, 2, 0, 42]))

    with scripted_peer(answer) as port, ModbusClient.tcp("127.0.0.1", port, slave=5, timeout=1) as client:
        with pytest.raises(ModbusUnitError, match="unit 9") as caught:
            client.read_holding_registers(0, 1, command="state")
        assert caught.value.unit == 9 and caught.value.command == "state" and caught.value.device
        with pytest.raises(ModbusLengthError, match="not a Modbus TCP header"):
            client.read_holding_registers(0, 1)
        assert client.read_holding_registers(0, 1) == (42,)


def test_unit_id_0xff_is_the_device_itself_on_modbus_tcp() -> None:
    server = _serve("modbus-tcp", _map(slave=7))
    try:
        with ModbusClient.tcp("127.0.0.1", int(server.port or 0), slave=0xFF, timeout=2) as client:
            assert client.read_holding_registers(100, 1) == (1000,)  # answered, the unit id echoed
        with pytest.raises(ValueError, match="slave id"):
            ModbusClient.tcp("127.0.0.1", int(server.port or 0), framing="rtu", slave=0xFF)
    finally:
        server.close()
