"""The WSG backend against devices that report odd system limits, and motions stopped mid-way (issue 12)."""

from __future__ import annotations

import logging
import math
import struct
import threading
import time

import pytest

import grippers
from grippers.drivers.errors import CommandFailed
from grippers.drivers.wsg.client import WsgClient
from grippers.drivers.wsg.protocol import Status
from grippers.drivers.wsg.sim import WsgModel, serve
from grippers.gripper import FastStopActive, GraspState


def _big_endian_as_float(value: int) -> float:
    """What a little-endian float reader makes of a big-endian u32 (the emulator of issue 12 §4)."""
    return struct.unpack("<f", struct.pack(">I", value))[0]


class _OddLimits(WsgModel):
    """A device whose 53h answer carries the given values (sent as they are: NaN, inf, negatives)."""

    def __init__(self, odd: dict[str, float], **kw) -> None:
        super().__init__(**kw)
        self.odd = odd

    def _system_limits(self, conn: int, f: dict, cmd: int) -> None:
        values = dict(
            stroke=self.stroke,
            min_speed=self.min_speed,
            max_speed=self.max_speed,
            min_acceleration=self.min_accel,
            max_acceleration=self.max_accel,
            min_force=self.min_force,
            nominal_force=self.nominal_force,
            overdrive_force=self.overdrive_force,
        )
        values.update(self.odd)
        self._reply(conn, cmd, Status.E_SUCCESS, **values)


@pytest.mark.parametrize(
    "odd",
    [
        {"max_speed": _big_endian_as_float(420)},  # a denormal: positive but absurd, with min 5 -> no range
        {"max_speed": -2.8e-17},
        {"stroke": math.nan, "nominal_force": math.inf},
        {"min_speed": 0.0, "min_force": -3.0},
        {"min_speed": 1e30},
    ],
)
def test_system_limits_that_cannot_be_limits_are_ignored_with_a_warning(odd, caplog) -> None:
    server = serve(_OddLimits(odd), "tcp://127.0.0.1:0", time_scale=50.0)
    try:
        with caplog.at_level(logging.WARNING, logger="grippers.backends.wsg"):
            g = grippers.open(server.url, profile="wsg50")
        try:
            limits = g.limits
            assert all(
                math.isfinite(v) and v >= 0
                for v in (
                    limits.max_width,
                    limits.min_speed,
                    limits.max_speed,
                    limits.min_force,
                    limits.max_force,
                )
            )
            assert limits.min_speed < limits.max_speed and limits.min_force < limits.max_force
            warnings = g.info().extra["warnings"]
            assert warnings and all("53h" in w and "ignored" in w for w in warnings)
            assert any("53h" in r.getMessage() for r in caplog.records)
            g.home()
            assert g.move(0.05, speed=0.05).width == pytest.approx(0.05, abs=1e-4)
        finally:
            g.close()
    finally:
        server.close()


def test_sane_system_limits_give_no_warning() -> None:
    g = grippers.open("sim://wsg50")
    try:
        assert g.info().extra["warnings"] == []
    finally:
        g.close()


def test_stopped_motions_end_aborted_and_the_grasp_state_is_the_devices() -> None:
    """Issue 12 §3 (WSG): stop from another thread during a blocking motion -> CommandFailed E_CMD_ABORTED,
    never a result; afterwards state().grasp is what the device reports (IDLE), not POSITIONING."""
    g = grippers.open("sim://wsg50")
    try:
        g.home()
        for start in (lambda: g.move(0.0, speed=0.01), lambda: g.grasp(0.0, speed=0.01, force=20.0)):
            timer = threading.Timer(0.1, g.stop)
            timer.start()
            t0 = time.monotonic()
            with pytest.raises(CommandFailed) as info:
                start()
            timer.join()
            assert info.value.status == Status.E_CMD_ABORTED and "aborted" in str(info.value)
            assert time.monotonic() - t0 < 5.0
            state = g.state()
            assert not state.moving
            assert state.grasp is GraspState.IDLE
            assert int(g.driver.grasping_state()) == 0  # the device's own answer
            g.move(0.1)
    finally:
        g.close()


def test_stop_is_sent_at_once_while_a_motion_exchange_is_pending_on_the_client() -> None:
    g = grippers.open("sim://wsg50")
    try:
        g.home()
        pending = g.driver.preposition(0.0, 5.0, wait=False)
        t0 = time.monotonic()
        g.driver.stop()
        assert time.monotonic() - t0 < 0.5
        with pytest.raises(CommandFailed, match="E_CMD_ABORTED"):
            pending.result(timeout=5.0)
        assert int(g.driver.grasping_state()) == 0  # IDLE, as the device reports
    finally:
        g.close()


def test_a_gripper_left_in_fast_stop_refuses_motion_from_open() -> None:
    """Manual 4.0.x §1.4.2: a TCP connection dropped without 07h leaves the WSG in FAST STOP. The next
    ``open()`` takes the device's latch before any state was read (``Device.fast_stop_latched``), so a motion
    says FastStopActive at once instead of reaching the device; acknowledge() clears it."""
    server = serve(WsgModel(), "tcp://127.0.0.1:0", time_scale=50.0)
    try:
        first = WsgClient.from_url(server.url, timeout=1.0)
        first.transport.close()  # the process dies: no 07h
        first.close()
        deadline = time.monotonic() + 5.0
        while not server.model.fast_stop:  # the simulator has seen the drop (its observable state)
            assert time.monotonic() < deadline, "the simulator never entered FAST STOP"
            time.sleep(0.005)
        with grippers.open(server.url, profile="wsg50") as g:
            with pytest.raises(FastStopActive):
                g.move(0.05)
            assert server.model.fast_stop  # refused here: nothing reached the device
            g.acknowledge()
            g.home()
            assert g.move(0.05, speed=0.05).width == pytest.approx(0.05, abs=1e-4)
    finally:
        server.close()
