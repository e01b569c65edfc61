"""The register model alone, in simulated time: activation, motion, parts, gOBJ, faults and their clearing."""

from __future__ import annotations

import pytest

from grippers.drivers.robotiq import modbus
from grippers.drivers.robotiq.modbus import RequestParser
from grippers.drivers.robotiq.registers import (
    COMMAND_ADDRESS,
    STATUS_ADDRESS,
    ActivationState,
    Command,
    Fault,
    ObjectDetection,
    Status,
)
from grippers.drivers.robotiq.sim import ModelParams, RobotiqModel


def _write(m: RobotiqModel, cmd: Command, now: float) -> None:
    (req,) = RequestParser(9).feed(modbus.write_request(9, COMMAND_ADDRESS, cmd.registers()))
    assert m.handle(req, now) == modbus.write_response(9, COMMAND_ADDRESS, 3)


def _read(m: RobotiqModel, now: float) -> Status:
    (req,) = RequestParser(9).feed(modbus.read_request(9, STATUS_ADDRESS, 3))
    reply = m.handle(req, now)
    assert reply is not None
    return Status.from_registers([int.from_bytes(reply[3 + 2 * i : 5 + 2 * i], "big") for i in range(3)])


def _active(part: float | None = None) -> RobotiqModel:
    m = RobotiqModel(ModelParams(), part_width_mm=part)
    _write(m, Command(act=True), 0.0)
    assert _read(m, 0.5).sta == ActivationState.IN_PROGRESS
    assert _read(m, 1.0).activated
    return m


GO = Command(act=True, gto=True, position=255, speed=255, force=255)


def test_activation_sweeps_for_a_second_then_completes_open() -> None:
    m = RobotiqModel()
    assert not _read(m, 0.0).act
    _write(m, Command(act=True), 0.0)
    mid = _read(m, 0.5)
    assert (
        mid.act and mid.sta == ActivationState.IN_PROGRESS and mid.position > 200
    )  # closed half-way through
    done = _read(m, 1.01)
    assert done.activated and done.position == 3


def test_motion_takes_the_speed_byte_s_time() -> None:
    m = _active()
    _write(m, Command(act=True, gto=True, position=230, speed=0, force=0), 1.0)  # 20 mm/s over 85 mm
    assert _read(m, 3.0).moving
    assert abs(m.width_mm() - (85 - 40)) < 0.5
    st = _read(m, 6.0)
    assert st.obj == ObjectDetection.AT_POSITION and st.position == 230 and st.current == 0


def test_a_part_stops_the_fingers_and_taking_it_away_loses_it() -> None:
    m = _active(part=40.0)
    _write(m, GO, 1.0)
    st = _read(m, 3.0)
    assert st.obj == ObjectDetection.CONTACT_CLOSING and abs(m.width_mm() - 40) < 0.5
    m.part_width_mm = None
    assert _read(m, 5.0).obj == ObjectDetection.AT_POSITION


def test_gto_without_activation_and_during_it() -> None:
    m = RobotiqModel()
    _write(m, Command(act=False, gto=True), 0.0)
    assert _read(m, 0.1).fault == Fault.ACTIVATION_BIT
    _write(m, Command(act=True), 0.2)
    _write(m, GO, 0.3)
    assert _read(m, 0.4).fault == Fault.ACTION_DELAYED
    st = _read(m, 1.3)  # activated at 1.2 s: the delayed action has run
    assert st.activated and st.fault == Fault.NONE and st.gto


@pytest.mark.parametrize("code", [0x0A, 0x0C, 0x0E])
def test_a_major_fault_halts_and_only_a_reset_clears_it(code: int) -> None:
    m = _active()
    _write(m, GO, 1.0)
    m.inject_fault(code)
    frozen = _read(m, 1.5).position
    assert _read(m, 2.0).position == frozen and _read(m, 2.0).fault == code
    _write(m, GO, 2.0)  # not heard
    assert _read(m, 2.1).fault == code
    _write(m, Command(), 2.2)
    assert _read(m, 2.3).fault == Fault.NONE
    _write(m, Command(act=True), 2.4)
    assert _read(m, 3.5).activated


def test_over_temperature_halts_until_it_cools() -> None:
    m = _active()
    m.inject_fault(Fault.TEMPERATURE)
    assert _read(m, 1.1).fault == Fault.TEMPERATURE
    m.clear_fault()
    assert _read(m, 1.2).fault == Fault.NONE


def test_an_activation_fault_needs_a_reset_and_a_new_activation() -> None:
    m = RobotiqModel()
    _write(m, Command(act=True), 0.0)
    m.inject_fault(Fault.ACTIVATION)
    assert _read(m, 0.1).fault == Fault.ACTIVATION
    _write(m, Command(), 0.2)
    _write(m, Command(act=True), 0.3)
    assert _read(m, 1.4).activated


@pytest.mark.parametrize("ard", [True, False])
def test_automatic_release(ard: bool) -> None:
    m = _active()
    _write(m, Command(act=True, gto=True, position=120, speed=255, force=255), 1.0)
    _read(m, 3.0)
    _write(m, Command(act=True, atr=True, ard=ard), 3.0)
    assert _read(m, 3.1).fault == Fault.AUTO_RELEASE_IN_PROGRESS
    st = _read(m, 10.0)
    assert st.fault == Fault.AUTO_RELEASE_COMPLETE and st.position == (3 if ard else 230)


def test_the_watchdog_notes_a_silence_until_the_next_write() -> None:
    m = RobotiqModel(ModelParams(watchdog_s=1.0))
    _write(m, Command(act=True), 0.0)
    assert _read(m, 0.9).fault == Fault.NONE
    assert _read(m, 2.5).fault == Fault.NO_COMMUNICATION
    _write(m, Command(act=True), 2.6)
    assert _read(m, 2.7).fault == Fault.NONE


def test_stop_clears_gto_and_the_fingers_halt() -> None:
    m = _active()
    _write(m, Command(act=True, gto=True, position=230, speed=0, force=0), 1.0)
    _read(m, 2.0)
    _write(m, Command(act=True, gto=False, position=230), 2.0)
    at = _read(m, 2.0).position
    assert not _read(m, 4.0).gto and _read(m, 4.0).position == at


def test_another_slave_a_broadcast_and_unknown_functions() -> None:
    m = RobotiqModel()
    other = modbus.Request(slave=8, function=3, address=STATUS_ADDRESS, count=3)
    assert m.handle(other, 0.0) is None
    broadcast = modbus.Request(
        slave=0, function=0x10, write_address=COMMAND_ADDRESS, values=Command(act=True).registers()
    )
    assert m.handle(broadcast, 0.0) is None and m.act
    reply = m.handle(modbus.Request(slave=9, function=0x06, address=COMMAND_ADDRESS, count=1), 0.0)
    assert reply == modbus.exception_response(9, 6, 1)
