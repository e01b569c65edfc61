"""SCHUNK's own driver against our simulator, as far as GPL code can be kept out of this repository: the
requests its ``Driver`` sends (schunk_gripper_library/driver.py at SCHUNK-SE-Co-KG/schunk_mechatronic_gripper
64cf163) were read from its source and are written here by hand, byte for byte, on the standard library's
HTTP client and, for Modbus RTU, on pymodbus (the peer SCHUNK's driver uses too).

Each command is the driver's three steps: POST the empty word (only bit 0, the active-low fast stop, set),
GET 0x0040 and keep bit 5, POST the command word; then poll 0x0040 until bit 5 has toggled and the pattern
the driver waits for matches (move: bits 4 and 13, or 7; grip: 4 and 12, or 11 with 4 clear, or 7; release:
4 and 13; stop: 4; acknowledge: 0; fast stop: 7).
"""

from __future__ import annotations

import http.client
import json
import struct
import time
from typing import Any
from urllib.parse import urlencode

import pytest

# The parameters the driver reads at connect (update_module_parameters: its readable_parameters.json entries
# whose names are in module_parameters), fieldbus first.
CONNECT = ["0x1130", "0x0500", "0x0540", "0x0588", "0x0600", "0x0608", "0x0630", "0x0650", "0x0660"]
CONNECT += ["0x1000", "0x1118"]
REGISTERS = {"0x0040": 8, "0x0048": 8, "0x1130": 1, "0x0500": 1, "0x1000": 8, "0x1118": 11}


class HttpPeer:
    """What SCHUNK's driver puts on the wire over the web API."""

    def __init__(self, port: int) -> None:
        self.conn = http.client.HTTPConnection("127.0.0.1", port, timeout=1.0)
        self.output = bytearray(16)

    def get(self, path: str) -> Any:
        self.conn.request("GET", path)
        reply = self.conn.getresponse()
        body = reply.read()
        assert 200 <= reply.status < 300, (path, reply.status, body)
        return json.loads(body)

    def read(self, inst: str) -> bytes:
        values = self.get(f"/adi/data.json?{urlencode({'inst': inst, 'count': '1'})}")
        assert values, inst
        return bytes.fromhex(values[0])

    def write(self, inst: str, data: bytes) -> None:
        body = urlencode({"inst": inst, "value": data.hex().upper()})
        self.conn.request(
            "POST", "/adi/update.json", body, {"Content-Type": "application/x-www-form-urlencoded"}
        )
        reply = self.conn.getresponse()
        assert json.loads(reply.read()) == {"result": 0}

    # -- the driver's buffer rules ----------------------------------------------------------------------

    def status_bit(self, bit: int) -> int:
        data = self.read("0x0040")
        return 1 if data[bit // 8] & (1 << bit % 8) else 0

    def bits(self) -> bytes:
        return self.read("0x0040")

    def clear(self) -> None:
        self.output = bytearray(16)
        self.output[0] |= 1  # bit 0 set: no fast stop

    def set_bit(self, bit: int, value: bool = True) -> None:
        if value:
            self.output[bit // 8] |= 1 << bit % 8
        else:
            self.output[bit // 8] &= ~(1 << bit % 8) & 0xFF

    def command(
        self, bits: list[int], *, position: int | None = None, speed: int | None = None, force=None
    ) -> int:
        """The three steps; returns bit 5 as it was before the command."""
        self.clear()
        self.write("0x0048", bytes(self.output))
        before = self.status_bit(5)
        for bit in bits:
            self.set_bit(bit)
        if position is not None:
            self.output[4:8] = struct.pack("<i", position)
        if speed is not None:
            self.output[8:12] = struct.pack("<i", speed)
        if force is not None:
            self.output[12:16] = struct.pack("<i", force)
        self.write("0x0048", bytes(self.output))
        return before

    def wait(self, before: int, patterns: list[dict[int, int]], timeout: float) -> dict[int, int]:
        deadline = time.monotonic() + timeout
        while time.monotonic() < deadline:
            data = self.bits()
            got = {b: 1 if data[b // 8] & (1 << b % 8) else 0 for b in range(32)}
            if got[5] != before:
                for pattern in patterns:
                    if all(got[b] == v for b, v in pattern.items()):
                        return pattern
            time.sleep(0.01)
        return {}

    def position(self) -> int:
        return struct.unpack("<i", self.bits()[4:8])[0]


@pytest.fixture
def peer(schunk_sim) -> tuple[Any, HttpPeer]:
    server = schunk_sim("schunk-egu-60", time_scale="10")
    return server, HttpPeer(server.port)


def test_connect_reads_every_parameter_and_show_specification_has_them(peer) -> None:
    server, p = peer
    assert p.get("/adi/data.json") == []  # connect(): a bare GET that answers 2xx
    values = {inst: p.read(inst) for inst in CONNECT}
    assert values["0x1130"] == b"\x02" and values["0x0500"] == b"\x0b"  # EtherNet/IP, EGU_60_M_B
    assert (
        struct.unpack("<f", values["0x0588"])[0] == 120.0
    )  # max_phys_stroke: show_specification's max_stroke
    assert struct.unpack("<f", values["0x0630"])[0] == 110.0  # max_vel
    assert struct.unpack("<f", values["0x0660"])[0] == 650.0  # max_grp_force
    assert values["0x1000"].decode().strip() == "SIM00001" and values["0x1118"].decode().strip()
    assert p.get("/adi/data.json?inst=0x0040&count=2") == []  # the dummy answers [] for another count
    assert p.get("/adi/data.json?inst=0x0041&count=1") == []  # and for an instance it lacks


def test_acknowledge_move_relative_move_grip_release_stop_fast_stop(peer) -> None:
    server, p = peer
    assert p.bits()[12] == 0xD9 and p.status_bit(7) == 1  # powers up in 0xD9, fast stop
    before = p.command([2])  # acknowledge
    assert p.wait(before, [{0: 1}], 1.0)

    before = p.command([13], position=50_000, speed=100_000)  # move_to_position(50000, 100000)
    assert p.wait(before, [{3: 0}], 0.1)  # the driver's start(): toggled, not "not feasible", in 0.1 s
    assert p.wait(before, [{4: 1, 13: 1}, {7: 1}], 5.0) == {4: 1, 13: 1}
    assert abs(p.position() - 50_000) <= 1

    before = p.command([14], position=-20_000, speed=100_000)  # is_absolute=False
    assert p.wait(before, [{4: 1, 13: 1}, {7: 1}], 5.0) == {4: 1, 13: 1}
    assert abs(p.position() - 30_000) <= 1

    with server.lock:
        server.model.part_width_mm = 20.0
    before = p.command([12], speed=0, force=50)  # grip(force=50): speed 0, the unit's grip speed
    assert p.wait(before, [{4: 1, 12: 1}, {4: 0, 11: 1}, {4: 0, 17: 1}, {7: 1}], 5.0) == {4: 1, 12: 1}
    assert abs(p.position() - 20_000) <= 1

    before = p.command([11])  # release(): opens by the release delta (5 mm)
    assert p.wait(before, [{4: 1, 13: 1}, {7: 1}], 5.0) == {4: 1, 13: 1}
    assert p.status_bit(12) == 0 and abs(p.position() - 25_000) <= 1

    before = p.command([13], position=110_000, speed=10_000)  # a slow move, then stop()
    assert p.wait(before, [{3: 0}], 0.1)
    before = p.command([1])
    assert p.wait(before, [{5: 1 - before, 4: 1}], 1.0)
    stopped = p.position()
    time.sleep(0.2)
    assert p.position() == stopped < 110_000

    p.clear()
    p.write("0x0048", bytes(p.output))
    before = p.status_bit(5)
    p.set_bit(0, False)  # fast_stop(): bit 0 low
    p.write("0x0048", bytes(p.output))
    assert p.wait(before, [{7: 1}], 1.0)
    assert p.bits()[12] == 0xD9

    before = p.command([13], position=60_000, speed=100_000)  # refused in error: only the toggle
    assert p.wait(before, [{7: 1}], 1.0)
    assert p.position() == stopped
    before = p.command([2])
    assert p.wait(before, [{0: 1, 7: 0}], 1.0)
    assert p.bits()[12] == 0


def test_a_lost_connection_answers_503_as_the_dummy_does(peer) -> None:
    server, p = peer
    p.conn.request("POST", "/adi/events.json", json.dumps({"lose_connection_sec": 60}))
    assert json.loads(p.conn.getresponse().read()) is True
    p.conn.request("GET", "/adi/data.json?inst=0x0040&count=1")
    assert p.conn.getresponse().status == 503


def test_the_same_sequence_over_modbus_rtu_with_pymodbus(schunk_sim) -> None:
    """The driver's Modbus side: holding registers from INST - 1, FC 03 and 16, device id 12, each
    register two bytes in the web API's order (pymodbus's registers, big-endian)."""
    pymodbus_client = pytest.importorskip("pymodbus.client")
    server = schunk_sim("schunk-egu-60", "pty", time_scale="10")
    client = pymodbus_client.ModbusSerialClient(port=server.path, baudrate=115200, parity="N", timeout=1.0)
    assert client.connect()
    try:

        def read(inst: int, count: int) -> bytes:
            pdu = client.read_holding_registers(address=inst - 1, count=count, device_id=12)
            assert not pdu.isError(), pdu
            return b"".join(r.to_bytes(2, "big") for r in pdu.registers)

        def write(inst: int, data: bytes) -> None:
            values = [int.from_bytes(data[i : i + 2], "big") for i in range(0, len(data), 2)]
            assert not client.write_registers(address=inst - 1, values=values, device_id=12).isError()

        assert read(0x1130, 1) == b"\x07\x00"  # Modbus
        assert read(0x0500, 1) == b"\x0b\x00"
        assert struct.unpack("<f", read(0x0588, 2))[0] == 120.0
        status = read(0x0040, 8)
        assert status[12] == 0xD9
        empty = bytes([1]) + bytes(15)
        write(0x0048, empty)
        before = read(0x0040, 8)[0] & 0x20
        write(0x0048, bytes([0x05]) + bytes(15))  # acknowledge
        after = read(0x0040, 8)
        assert after[0] & 0x20 != before and after[0] & 0x01
        write(0x0048, empty)
        write(0x0048, bytes([0x01, 0x20, 0, 0]) + struct.pack("<ii", 40_000, 100_000) + bytes(4))
        deadline = time.monotonic() + 5
        while time.monotonic() < deadline and not read(0x0040, 8)[1] & 0x20:  # bit 13, position reached
            time.sleep(0.01)
        assert struct.unpack("<i", read(0x0040, 8)[4:8])[0] == 40_000
        assert client.read_holding_registers(
            address=0x0041 - 1, count=1, device_id=12
        ).isError()  # no such inst
    finally:
        client.close()


# The cases below were found by running SCHUNK's driver itself against the simulator, once, outside this
# repository (docs/protocols-schunk.md, "SCHUNK's driver against our simulator"); each replays the driver's
# requests for the call that failed, written by hand from driver.py as above.


def test_release_after_an_outward_grip_closes_away_from_the_part(peer) -> None:
    """grip(force=50, outward=True) on a part's bore, then release(): the jaws sit inside the part, so
    releasing closes them by the release delta, and nothing is in the way (the driver waits for 4 and 13)."""
    server, p = peer
    with server.lock:
        server.model.part_width_mm = 40.0
    assert p.wait(p.command([2]), [{0: 1}], 1.0)
    before = p.command([13], position=20_000, speed=100_000)  # inside the bore first
    assert p.wait(before, [{4: 1, 13: 1}, {7: 1}], 5.0) == {4: 1, 13: 1}
    before = p.command([12, 7], speed=0, force=50)  # grip(force=50, outward=True)
    assert p.wait(before, [{4: 1, 12: 1}, {4: 0, 11: 1}, {4: 0, 17: 1}, {7: 1}], 5.0) == {4: 1, 12: 1}
    assert abs(p.position() - 40_000) <= 1
    before = p.command([11])  # release()
    assert p.wait(before, [{4: 1, 13: 1}, {7: 1}], 5.0) == {4: 1, 13: 1}
    assert abs(p.position() - 35_000) <= 1 and p.status_bit(12) == 0


def test_an_inward_grip_still_holds_the_part_against_closing(peer) -> None:
    """The other side of the same rule: after an inward grip the jaws are outside the part, so a move
    that closes them further stops at the part (4 without 13), and release opens freely."""
    server, p = peer
    with server.lock:
        server.model.part_width_mm = 40.0
        server.model.position_mm = 60.0
    assert p.wait(p.command([2]), [{0: 1}], 1.0)
    before = p.command([12], speed=0, force=50)
    assert p.wait(before, [{4: 1, 12: 1}, {7: 1}], 5.0) == {4: 1, 12: 1}
    before = p.command([13], position=30_000, speed=100_000)
    assert p.wait(before, [{4: 1}, {7: 1}], 5.0) == {4: 1}
    assert p.status_bit(13) == 0 and abs(p.position() - 40_000) <= 1
    before = p.command([11])
    assert p.wait(before, [{4: 1, 13: 1}, {7: 1}], 5.0) == {4: 1, 13: 1}
    assert abs(p.position() - 45_000) <= 1


def test_grip_at_an_expected_position_without_a_part_ends_past_it_by_the_margin(peer) -> None:
    """grip(force=50, position=30000, velocity=20000) with nothing between the jaws: the driver allows
    |position - actual| / velocity + 0.5 s (estimate_duration), so the unit must give up near the expected
    position (past it by grp_pos_margin, 0x0580) with "no workpiece" (11, 4 clear), not close to the end."""
    server, p = peer
    assert p.wait(p.command([2]), [{0: 1}], 1.0)
    before = p.command([13], position=100_000, speed=100_000)
    assert p.wait(before, [{4: 1, 13: 1}, {7: 1}], 5.0) == {4: 1, 13: 1}
    margin_um = round(struct.unpack("<f", p.read("0x0580"))[0] * 1000)
    before = p.command([16], position=30_000, speed=20_000, force=50)
    patterns = [{4: 1, 12: 1}, {4: 0, 11: 1}, {4: 0, 17: 1}, {7: 1}]
    assert p.wait(before, patterns, 5.0) == {4: 0, 11: 1}
    assert abs(p.position() - (30_000 - margin_um)) <= 1


def test_brake_test_reports_success_as_the_dummy_does(peer) -> None:
    """brake_test(): control bit 30; the driver waits 4 s for bit 4 (the dummy sets it at once)."""
    server, p = peer
    assert p.wait(p.command([2]), [{0: 1}], 1.0)
    before = p.command([30])
    assert p.wait(before, [{4: 1}, {3: 1}, {7: 1}], 1.0) == {4: 1}


@pytest.mark.parametrize("transport", ["http", "pty"])
def test_every_parameter_in_the_drivers_list_reads_at_its_size(schunk_sim, transport) -> None:
    """SCHUNK's own tests (test_module_parameters.py) read every instance of its readable_parameters.json
    and expect the register count's bytes, except 0x11A0/0x11A8 (baud rate, id) on Ethernet units and
    0x1138 (MAC) on Modbus ones: the unit files in its dummy have them all."""
    from grippers.drivers.schunk.protocol import PARAMETERS

    # instance: registers, from the driver's config/readable_parameters.json
    listed = {0x0040: 8, 0x0048: 8, 0x0118: 1, 0x0120: 1, 0x0128: 1, 0x0130: 107, 0x0230: 2, 0x0238: 2}
    listed |= {0x0380: 1, 0x03A8: 2, 0x03B0: 12, 0x03B8: 12, 0x0500: 1, 0x0528: 2, 0x0540: 2, 0x0580: 2}
    listed |= {inst: 2 for inst in (0x0588, 0x05A8, 0x0600, 0x0608, 0x0610, 0x0628, 0x0630, 0x0650)}
    listed |= {inst: 2 for inst in (0x0658, 0x0660, 0x06A8, 0x0800, 0x0808, 0x0810, 0x0818, 0x0820)}
    listed |= {inst: 2 for inst in (0x0828, 0x0840, 0x0870, 0x0878, 0x0880, 0x0888, 0x0890, 0x0898)}
    listed |= {0x08A0: 2, 0x08A8: 2, 0x1000: 8, 0x1008: 8, 0x1020: 2, 0x1100: 6, 0x1108: 5, 0x1110: 1}
    listed |= {0x1118: 11, 0x1130: 1, 0x1138: 3, 0x11A0: 2, 0x11A8: 1, 0x1330: 1, 0x1400: 2}
    assert all(PARAMETERS[inst].registers == n for inst, n in listed.items())
    if transport == "http":
        server = schunk_sim("schunk-egu-60")
        p = HttpPeer(server.port)
        absent = {0x11A0, 0x11A8}
        for inst, registers in listed.items():
            values = p.get(f"/adi/data.json?inst=0x{inst:04X}&count=1")
            if inst in absent:
                assert values == [], hex(inst)
                continue
            assert values, hex(inst)
            data = bytes.fromhex(values[0])
            assert 0 < len(data) <= 2 * registers, hex(inst)  # the driver zero-pads a short answer
        return
    pymodbus_client = pytest.importorskip("pymodbus.client")
    server = schunk_sim("schunk-egu-60", "pty")
    client = pymodbus_client.ModbusSerialClient(port=server.path, baudrate=115200, parity="N", timeout=1.0)
    assert client.connect()
    try:
        for inst, registers in listed.items():
            pdu = client.read_holding_registers(address=inst - 1, count=registers, device_id=12)
            if inst == 0x1138:
                assert pdu.isError(), hex(inst)
                continue
            assert not pdu.isError() and len(pdu.registers) == registers, hex(inst)
        slave = client.read_holding_registers(address=0x11A8 - 1, count=1, device_id=12).registers
        assert slave[0] >> 8 == 12  # the id in the first byte, as the unit's enum-like uint8
    finally:
        client.close()
