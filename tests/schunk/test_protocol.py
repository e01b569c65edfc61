"""The sans-IO core against the bytes SCHUNK's own sources hold (schunk_gripper_dummy config/grippers/*.json,
read from real units, and the driver's bit and byte rules): facts only, written here by hand."""

from __future__ import annotations

import pytest

from grippers.drivers.schunk.protocol import (
    ERR_FAST_STOP,
    CodecError,
    CommandTracker,
    Control,
    ControlWord,
    Fieldbus,
    Outcome,
    ProcessInput,
    Status,
    decode,
    encode,
    error_name,
    padded,
    profile_name,
)

EI, PN = Fieldbus.ETHERNET_IP, Fieldbus.PROFINET


def test_the_power_up_input_of_an_egu_60_on_ethernet_ip() -> None:
    # EGU_60_EI_M_B.json, 0x0040: error bit 7 and GPE bit 31, 251 µm, error 0xD9 at byte 12.
    pi = ProcessInput.decode(bytes.fromhex("80000080FB00000000000000D9000000"), EI)
    assert pi.status == Status.ERROR | Status.GPE
    assert (pi.position_um, pi.error, pi.warning, pi.additional) == (251, ERR_FAST_STOP, 0, 0)
    assert pi.encode(EI).hex().upper() == "80000080FB00000000000000D9000000"


def test_profinet_turns_the_position_and_the_diagnostics_big_endian() -> None:
    # EGU_60_PN_M_B.json, 0x0040: -377 µm big-endian, and the error code in the last byte.
    pi = ProcessInput.decode(bytes.fromhex("80000080FFFFFE8700000000000000D9"), PN)
    assert (pi.position_um, pi.error) == (-377, ERR_FAST_STOP)
    assert pi.has(Status.ERROR) and not pi.has(Status.READY)


@pytest.mark.parametrize(
    ("inst", "hex_ei", "hex_pn", "value"),
    [
        (0x0588, "0000F042", "42F00000", 120.0),  # max_phys_stroke of the EGU 60, mm
        (0x0630, "0000DC42", "42DC0000", 110.0),  # max_vel, mm/s
        (0x0660, "00802244", "44228000", 650.0),  # max_grp_force, N
    ],
)
def test_floats_follow_the_fieldbus_byte_order(inst: int, hex_ei: str, hex_pn: str, value: float) -> None:
    assert decode(inst, bytes.fromhex(hex_ei), EI) == value
    assert decode(inst, bytes.fromhex(hex_pn), PN) == value
    assert encode(inst, value, EI).hex().upper() == hex_ei
    assert encode(inst, value, PN).hex().upper() == hex_pn


def test_an_enum_is_its_first_byte_and_a_text_is_stripped() -> None:
    assert decode(0x0500, bytes.fromhex("0B"), EI) == 11  # the web API sends one byte
    assert decode(0x0500, bytes.fromhex("0B00"), PN) == 11  # Modbus, a register of two
    assert decode(0x1000, b"NSNS0667        ", EI) == "NSNS0667"
    assert decode(0x1000, b"NSNS0666" + bytes(8), PN) == "NSNS0666"
    with pytest.raises(CodecError):
        decode(0x1000, bytes([0xFF] * 16), EI)
    with pytest.raises(CodecError):
        padded(0x0500, b"\x00\x00\x00")  # longer than the parameter


def test_control_bits_sit_in_byte_n_div_8_on_every_fieldbus() -> None:
    word = ControlWord(Control.FAST_STOP_OFF | Control.MOVE_ABSOLUTE, 50_000, 20_000, 0)
    for bus in (EI, PN):
        data = word.encode(bus)
        assert data[:4] == bytes([0x01, 0x20, 0x00, 0x00])  # bit 0, bit 13 = byte 1 bit 5
        assert ControlWord.decode(data, bus) == word
    assert word.encode(EI)[4:8] == (50_000).to_bytes(4, "little")
    assert word.encode(PN)[4:8] == (50_000).to_bytes(4, "big")
    assert ControlWord(Control.FAST_STOP_OFF | Control.GPE).encode(EI)[3] == 0x80  # bit 31
    assert not ControlWord(Control.FAST_STOP_OFF).is_command  # only bit 0: no command
    assert ControlWord(Control(0)).is_command  # bit 0 low: the fast stop


def test_outcome_bits_left_from_the_last_command_never_end_the_next_one() -> None:
    before = ProcessInput(Status.READY | Status.SUCCESS | Status.REACHED, 0, 0, 0, 0)  # the last move's end
    tracker = CommandTracker.after(before, "move")
    assert tracker.outcome(before) is Outcome.PENDING  # bit 5 has not toggled: not this command's bits
    running = ProcessInput(Status.READY | Status.RECEIVED, 10, 0, 0, 0)
    assert tracker.outcome(running) is Outcome.PENDING
    done = ProcessInput(Status.READY | Status.RECEIVED | Status.SUCCESS | Status.REACHED, 50, 0, 0, 0)
    assert tracker.outcome(done) is Outcome.DONE
    blocked = ProcessInput(Status.READY | Status.RECEIVED | Status.SUCCESS, 30, 0, 0, 0)
    assert tracker.outcome(blocked) is Outcome.BLOCKED
    error = ProcessInput(Status.RECEIVED | Status.ERROR, 30, 0xEF, 0, 0)
    assert tracker.outcome(error) is Outcome.ERROR


def test_grip_outcomes_and_names() -> None:
    t = CommandTracker(False, "grip")
    received = Status.READY | Status.RECEIVED
    assert t.outcome(ProcessInput(received | Status.GRIPPED | Status.SUCCESS, 0, 0, 0, 0)) is Outcome.GRIPPED
    assert t.outcome(ProcessInput(received | Status.NO_WORKPIECE, 0, 0, 0, 0)) is Outcome.NO_WORKPIECE
    assert t.outcome(ProcessInput(received | Status.WRONG_WORKPIECE, 0, 0, 0, 0)) is Outcome.WRONG_WORKPIECE
    assert t.outcome(ProcessInput(received | Status.NOT_FEASIBLE, 0, 0, 0, 0)) is Outcome.NOT_FEASIBLE
    assert error_name(0xD9) == "ERR_FAST_STOP" and error_name(0xEF) == "error 0xEF"
    assert profile_name("EGU_60_M_B") == "schunk-egu-60" and profile_name("EGK_25_N_SD") == "schunk-egk-25"


def test_the_monitor_reads_a_command_and_a_status_poll() -> None:
    from grippers.drivers import modbus
    from grippers.drivers.dissect import FROM_GRIPPER, TO_GRIPPER
    from grippers.drivers.schunk.dissect import SchunkDissector
    from grippers.drivers.schunk.rtu import registers_of

    d = SchunkDissector()
    word = ControlWord(Control.FAST_STOP_OFF | Control.MOVE_ABSOLUTE, 50_000, 20_000, 0).encode(
        Fieldbus.MODBUS
    )
    (rec,) = d.feed(TO_GRIPPER, modbus.write_request(12, 0x0047, registers_of(word)), None)
    assert rec["text"] == (
        "id 12 write 0x0048 plc_sync_output: FAST_STOP_OFF|MOVE_ABSOLUTE target 50000 um at 20000 um/s, "
        "force 0 %"
    )
    (rec,) = d.feed(TO_GRIPPER, modbus.read_request(12, 0x003F, 8), None)
    assert rec["text"] == "id 12 read 0x0040 plc_sync_input x8"
    status = ProcessInput(Status.ERROR, 251, ERR_FAST_STOP, 0, 0).encode(Fieldbus.MODBUS)
    (rec,) = d.feed(FROM_GRIPPER, modbus.read_response(12, 3, registers_of(status)), None)
    assert rec["text"] == "id 12: 0x0040 plc_sync_input = ERROR at 251 um ERR_FAST_STOP"
