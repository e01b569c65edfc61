"""The MSG simulator keeps the firmware's timing and state (issue 19 §1; docs/protocols.md §2, "Firmware
timing and state a client must survive"). Raw frames (identifiers and bytes built by hand, no client code)
fed to the model at explicit SIMULATED times, so every window (one 160 us control tick, a 10 ms poll
period, the 60 ms current ramp) is exact, whatever the machine's load."""

from __future__ import annotations

import struct

import pytest

from grippers.drivers.stepfoc.sim import MsgModel
from grippers.drivers.stepfoc.sim.model import Phase
from grippers.drivers.stepfoc.speed import SPECTRAL_MICRO, STEPFOC, ticks_per_s

from ..rawmodel import RawModel, cmd61, ident

ESTOP, IDLE, SAVE, RESET, WATCHDOG, HEARTBEAT, IQ, ENCODER = 0, 12, 13, 14, 15, 9, 27, 28
HEARTBEAT_SETUP, CMD_61, STATUS_60, CALIBRATE = 30, 61, 60, 62
ACTIVATE, ACTION = 0x80, 0x40
F_CALIBRATED, F_TIMEOUT = 0x01, 0x04


class Raw(RawModel):
    def __init__(self, model: MsgModel) -> None:
        super().__init__(model, dt=0.001, step=0.01)
        model.advance(0.0)

    def poll(self, dt: float = 0.001) -> tuple[int, int, int, int]:
        """(position, current, flags, detection) of the 60 reply to an empty 61."""
        return self.status(dt)[:4]

    def encoder(self) -> tuple[int, int]:
        (reply,) = self.send(ENCODER, remote=True)
        return struct.unpack(">ii", reply.data)

    def calibrate(self, limit: float = 60.0) -> None:
        self.send(CALIBRATE)
        end = self.t + limit
        while self.m.calibrating and self.t < end:
            self.run(0.05)
        assert self.m.calibrated and not self.m.calibrating

    def go(self, position: int, **kw: int) -> None:
        self.send(CMD_61, cmd61(position, **kw))
        self.run(0.5)
        while self.m.phase in (Phase.STARTING, Phase.MOVING):
            self.run(0.05)


def test_power_up_detection_3_default_stops_and_ticks_towards_open() -> None:
    r = Raw(MsgModel(current_noise=False))
    position, current, flags, detection = r.poll()
    # common.h: object_detection_status = 3; stops 10329 / -229 until calibrated; encoder 0 reads 249
    assert (position, detection, flags & F_CALIBRATED) == (249, 3, 0)
    before, _ = r.encoder()
    r.send(CALIBRATE)
    r.run(0.5)  # Calibrate_gripper opens first, with a positive velocity
    after, velocity = r.encoder()
    assert after > before and velocity == ticks_per_s(STEPFOC.calibration_speed) == 5166


def test_the_latch_is_the_nodes_and_survives_a_new_session_and_a_calibration() -> None:
    """Issue 19's "run twice": the second run's first 61 equals the first run's last one."""
    r = Raw(MsgModel())
    r.calibrate()
    r.go(60, current=500)  # session 1: move, arrive (latch set)
    assert r.poll()[3] == 3
    r.calibrate()  # session 2: home() ...
    assert r.poll()[0] == 255
    r.send(CMD_61, cmd61(60, current=500))  # ... then the same move: byte-identical to session 1's last
    r.run(0.01)
    position, _, _, detection = r.poll()
    assert detection == 3 and position > 200  # "arrived" while the jaws are still far from 60


def test_a_poll_within_one_control_tick_cancels_the_latch_reset() -> None:
    raced, clean = Raw(MsgModel()), Raw(MsgModel())
    for r in (raced, clean):
        r.calibrate()
        r.go(100)
        r.send(CMD_61, cmd61(200, speed=10))  # a new, different command from rest at 100
    raced.poll(dt=0.00005)  # 50 us later: before the next 160 us tick ran Gripper_mode
    clean.poll(dt=0.001)  # 1 ms later: the latch was reset
    raced.run(0.05)
    clean.run(0.05)
    assert raced.poll()[3] == 3 and raced.poll()[0] < 190  # "at position" throughout the motion
    assert clean.poll()[3] == 0


def test_end_of_a_recalibration_position_high_and_current_low_before_the_jaws_rest() -> None:
    r = Raw(MsgModel(current_noise=False))
    r.calibrate()
    r.go(128)
    r.send(CALIBRATE)
    early = None
    while r.m.calibrating:
        position, current, _, _ = r.poll(dt=0.01)  # a 10 ms poll period
        if early is None and position >= 250 and abs(current) < 300:
            early = r.t
    # the polls saw "position >= 250, little current" while the calibration still ran: ~40 ms of approach and
    # ~60 ms of current ramp at the stop
    assert early is not None and r.t - early >= 0.08
    assert r.poll()[0] == 255 and r.m.phase is Phase.IDLE


def test_an_aborted_calibration_resumes_where_it_stopped() -> None:
    r = Raw(MsgModel())
    r.calibrate()
    r.go(255, current=501)  # jaws closed
    r.send(CALIBRATE)
    r.run(6.0)  # opened (21000 ticks at 5166 ticks/s), paused, closing
    assert r.m.phase is Phase.CAL_CLOSE
    r.send(CMD_61, cmd61(100, current=502))  # a 5-byte 61 aborts it
    r.run(0.05)
    assert not r.m.calibrating
    r.go(100, current=503)
    lowest = 255
    r.send(CALIBRATE)  # resumes: only the closing step is left
    while r.m.calibrating:
        r.run(0.05)
        lowest = min(lowest, r.poll()[0])
    assert lowest >= 100 and r.poll()[0] == 255  # never went back to the open stop


def test_calibration_ticks_add_up_across_aborts_to_the_150000_tick_time_out() -> None:
    r = Raw(MsgModel(current_noise=False))
    r.calibrate()
    spent = 0.0
    current = 400
    while spent < 24.0:  # 150,000 ticks at 6250 Hz
        r.go(255, current=current)
        r.send(CALIBRATE)
        r.run(3.0)  # still opening: never reaches a stop
        spent += 3.0
        current += 1
        r.send(CMD_61, cmd61(255, current=current))  # abort; back to the closed stop for the next one
        assert r.m.calibrated or spent >= 24.0
    assert not (r.poll()[2] & F_CALIBRATED)  # the time-out cleared the bit, and idled the driver


def test_heartbeat_9_only_after_silence() -> None:
    r = Raw(MsgModel(node=0))
    r.send(HEARTBEAT_SETUP, struct.pack(">I", 100))
    beats = []
    for _ in range(20):  # polled every 50 ms: every reply restarts the timer, so no heartbeat
        r.poll(dt=0.05)
        beats += r.m.due_frames(r.t)
    assert beats == []
    r.t += 0.11
    (beat,) = r.m.due_frames(r.t)
    assert beat.arbitration_id == ident(HEARTBEAT) and beat.data == b""


@pytest.mark.parametrize(
    ("feeder", "trips"),
    [
        ((CMD_61, b"", False), False),  # polls feed it
        ((2, bytes(8), False), False),  # data pack 1 (position, velocity or current loop: 8, 5 or 2 bytes)
        ((2, bytes(2), False), False),
        ((2, bytes(3), False), True),  # a wrong length (Wrong_DL) does not
        ((4, bytes(8), False), False),  # the PD data pack feeds it
        ((6, bytes(8), False), True),  # data packs 2 and 3 (6, 8) do nothing at all
        ((ENCODER, b"", True), False),  # remote requests feed it
        ((CALIBRATE, b"", False), True),  # 62 does not
        ((IDLE, b"", False), True),
        ((HEARTBEAT_SETUP, struct.pack(">I", 0), False), True),
    ],
)
def test_watchdog_is_fed_only_by_some_frames(feeder: tuple[int, bytes, bool], trips: bool) -> None:
    r = Raw(MsgModel())
    r.poll()
    r.send(WATCHDOG, struct.pack(">IB", 200, 0))
    r.poll()
    command, data, remote = feeder
    for _ in range(10):  # every 50 ms for half a second, against a 200 ms watchdog
        r.send(command, data, remote=remote, dt=0.05)
    r.m.advance(r.t)  # the server's loop advances the model between frames too
    assert r.m.timeout_error is trips


def test_save_stores_the_watchdog_so_it_trips_after_a_reset_unless_polled() -> None:
    r = Raw(MsgModel())
    r.poll()
    r.send(WATCHDOG, struct.pack(">IB", 200, 0))
    r.send(SAVE)
    r.send(RESET)
    r.run(0.3)
    assert r.poll()[2] & F_TIMEOUT


def test_current_noise_and_offset_are_deterministic_for_a_seed_and_on_by_default() -> None:
    def readings(model: MsgModel) -> list[int]:
        r = Raw(model)
        return [r.poll()[1] for _ in range(50)]

    a, b = readings(MsgModel(seed=7)), readings(MsgModel(seed=7))
    assert a == b and len(set(a)) > 3  # noisy, and the same noise for the same seed
    assert readings(MsgModel(seed=8)) != a
    assert set(readings(MsgModel(current_noise=False))) == {0}
    assert abs(sum(a) / len(a)) <= 40  # an offset of tens of mA at most


def test_a_part_is_flagged_late_at_low_speed() -> None:
    r = Raw(MsgModel(part_width_mm=50.0, current_noise=False))
    r.calibrate()
    r.go(0, current=501)
    r.send(CMD_61, cmd61(255, speed=0, current=800))
    while r.m.phase is not Phase.PUSHING:
        r.run(0.05)
    contact = r.t
    while r.poll(dt=0.05)[3] != 1:
        assert r.t - contact < 5.0
    # 800 mA in about 2.5 s at speed 0: 80 % of 800 mA (from the ~120 mA running current) after 1.5-2 s
    assert 1.4 <= r.t - contact <= 2.1


def test_the_first_current_request_at_high_speed_flags_an_object_before_the_jaws_move() -> None:
    r = Raw(MsgModel(current_noise=False))
    r.calibrate()
    r.go(100)
    start = r.poll()[0]
    r.send(CMD_61, cmd61(200, speed=255, current=400))  # 360 mA first request > 80 % of 400 mA
    position, current, _, detection = r.poll(dt=0.001)
    assert detection == 1 and position == start and current == -360
    r.run(0.02)
    assert r.poll()[3] == 0  # then it moves freely


@pytest.mark.parametrize(("driver", "held"), [(STEPFOC, True), (SPECTRAL_MICRO, False)])
def test_stop_keeps_the_part_on_stepfoc_and_releases_it_on_spectral_micro(driver, held: bool) -> None:
    r = Raw(MsgModel(part_width_mm=50.0, current_noise=False, driver=driver))
    r.calibrate(limit=120.0)
    r.go(0, current=501)
    r.go(255, current=600)
    assert r.poll()[3] == 1
    r.send(CMD_61, cmd61(255, current=600, flags=ACTIVATE))  # action 0: stop
    r.run(0.1)
    _, current, _, detection = r.poll()
    assert (detection == 1 and abs(current) > 400) is held
    assert (detection == 0 and current == 0) is not held


def test_spectral_micro_calibrates_slower_with_its_own_constants() -> None:
    times = {}
    for driver in (STEPFOC, SPECTRAL_MICRO):
        r = Raw(MsgModel(driver=driver, current_noise=False))
        r.send(CALIBRATE)
        r.run(0.5)
        assert abs(r.encoder()[1]) == ticks_per_s(driver.calibration_speed, driver)
        while r.m.calibrating:
            r.run(0.05)
        times[driver.name] = r.t
    # Spectral Micro holds each stop 3200 ticks (0.64 s at 5000 Hz) and runs at speed 40 of its own map
    assert ticks_per_s(40, SPECTRAL_MICRO) == 40 + 40 * (80000 - 40) // 255
    assert times["spectral-micro"] != times["stepfoc"]


# Issue 33 §4, read against PCrnjak/STEPFOC-stepper-controller at 6e71832, "STEPFOC firmware/src/":
# communication_CAN.cpp 310-403 (61: Same_command from previousBytes 318-325, mode 11 at 356, previousBytes
# kept at 360-363), 678-695 (62: mode 7 only); motor_control.cpp 2223-2298 (Gripper_mode), 2305-2421
# (Calibrate_gripper). docs/reliability.md, "Round 4", has the reading.


def test_an_identical_61_after_a_calibration_keeps_the_latch_and_still_moves_the_jaws() -> None:
    """(a) Calibrate_gripper writes neither Same_command, At_position nor previousBytes, so a 61 identical
    to the last one keeps the at-position latch (Gripper_mode resets it only when Same_command == 0, 2226-
    2229): detection 3 at once. But the 61 still sets mode 11 and Gripper_mode, latched, runs Position_mode
    (2250-2254) towards the stored setpoint mapped with the new stops (2232): the jaws DO travel to it."""
    r = Raw(MsgModel(current_noise=False))
    r.calibrate()
    r.go(60, current=500)
    assert r.poll()[3] == 3
    r.calibrate()
    assert r.poll()[0] == 255
    r.send(CMD_61, cmd61(60, current=500))  # byte for byte the last one
    seen = []
    for _ in range(100):  # a second of device time, polled every 10 ms
        position, _, _, detection = r.poll(dt=0.01)
        seen.append((position, detection))
    assert all(d == 3 for _, d in seen)  # "at position" throughout
    assert seen[0][0] > 200 and abs(seen[-1][0] - 60) <= 1  # ... while the jaws travelled from 255 to 60


def test_a_61_aborting_the_closing_phase_makes_the_next_62_close_at_once() -> None:
    """(b) The 61 leaves grip_cal_1 and grip_delay_1 set (reset only at the end, 2386-2392, or the time-out,
    2408-2414); the next 62 only sets mode 7 (689), and the first Calibrate_gripper step is the closing one
    (2321) while the opening one (2342) is skipped: the jaws close at once instead of opening again."""
    r = Raw(MsgModel(current_noise=False))
    r.calibrate()
    r.go(255, current=501)
    r.send(CALIBRATE)
    r.run(6.0)  # opened, paused, closing
    assert r.m.phase is Phase.CAL_CLOSE
    r.send(CMD_61, cmd61(100, current=502))  # aborts it
    r.run(3.0)
    assert not r.m.calibrating
    before, _ = r.encoder()
    r.send(CALIBRATE)
    assert r.m.phase is Phase.CAL_CLOSE  # the closing step at once
    r.run(0.2)
    after, velocity = r.encoder()
    assert velocity < 0 and after < before  # ticks grow towards open: it closes, it does not open first
