"""Fixtures for the STEPFOC CAN tests: simulators on python-can ``virtual`` buses with unique channel names.

Each test gets its own channel, so tests never see each other's frames even when run in one process.
"""

from __future__ import annotations

import uuid
from collections.abc import Callable, Iterator

import can
import pytest

from grippers.drivers.stepfoc.can_client import StepfocBus
from grippers.drivers.stepfoc.sim import MsgModel, serve_can
from grippers.drivers.stepfoc.sim.can_server import CanSimServer

from ...closing import closed_after

TIME_SCALE = 200.0  # simulated seconds per wall second: calibration (~8 s simulated) takes ~40 ms


@pytest.fixture
def channel() -> str:
    return f"stepfoc-test-{uuid.uuid4().hex[:12]}"


@pytest.fixture
def start_sim(channel: str) -> Iterator[Callable[..., CanSimServer]]:
    """Start a simulator serving the given models on this test's virtual channel; closed after the test."""

    def start(*models: MsgModel, time_scale: float = TIME_SCALE) -> CanSimServer:
        return serve_can(list(models) or [MsgModel()], f"can://virtual/{channel}", time_scale=time_scale)

    with closed_after(start) as started:
        yield started


@pytest.fixture
def sim(start_sim: Callable[..., CanSimServer]) -> CanSimServer:
    """One uncalibrated MSG 150 as node 0."""
    return start_sim(MsgModel(node=0))


@pytest.fixture
def canbus(channel: str) -> Iterator[StepfocBus]:
    with StepfocBus(interface="virtual", channel=channel) as bus:
        yield bus


@pytest.fixture
def spy(channel: str) -> Iterator[can.BusABC]:
    """A second raw bus on the channel: sees every frame the client and the simulator send."""
    bus = can.Bus(interface="virtual", channel=channel)
    yield bus
    bus.shutdown()


def drain(bus: can.BusABC, wait: float = 0.05) -> list[can.Message]:
    """Every frame the spy bus has received (waits ``wait`` for stragglers)."""
    out = []
    while (msg := bus.recv(timeout=wait)) is not None:
        out.append(msg)
    return out


@pytest.fixture
def drain_frames() -> Callable[..., list[can.Message]]:
    return drain
