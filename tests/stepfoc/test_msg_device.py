"""The driver's MSG device (drivers/stepfoc/device.py) on its own, in device units, over both links: what the
backend maps SI onto (issue 32 §1: one device object, one motion-end rule, the supersede counter)."""

from __future__ import annotations

import contextlib
import threading
import uuid
from collections.abc import Iterator

import pytest

from grippers.drivers.errors import CommandFailed
from grippers.drivers.stepfoc.can_protocol import Detection
from grippers.drivers.stepfoc.device import NOT_CALIBRATED, CanLink, StepfocDevice, UartLink
from grippers.drivers.stepfoc.sim import MsgModel, serve_can, serve_uart
from tests.simhold import MSG_CREEP_S, held, step_until


@contextlib.contextmanager
def device(transport: str) -> Iterator[tuple[object, StepfocDevice]]:
    """A simulated MSG at 50x and the driver device over the given link."""
    if transport == "can":
        channel = f"msg-device-{uuid.uuid4().hex[:8]}"
        with serve_can([MsgModel(node=0)], f"can://virtual/{channel}", time_scale=50.0) as server:
            dev = StepfocDevice(CanLink("virtual", channel, 1_000_000, 0, 1000, 0.5))
            try:
                yield server, dev
            finally:
                dev.close()
    else:
        with serve_uart(MsgModel(node=0), "pty", time_scale=50.0) as server:
            dev = StepfocDevice(UartLink(server.url, 115200, 1000, 0.5))
            try:
                yield server, dev
            finally:
                dev.close()


@pytest.mark.parametrize("transport", ["can", "pty"])
def test_calibrate_then_go_ends_at_the_target_byte(transport: str) -> None:
    with device(transport) as (_server, dev):
        with pytest.raises(CommandFailed) as refused:
            dev.require_calibrated("move")  # a fresh simulator is not calibrated: nothing is sent
        assert refused.value.status_name == NOT_CALIBRATED
        dev.calibrate(30.0)
        assert dev.require_calibrated("move") is None  # the calibration's polls said so: no read
        st = dev.go("move", 100, 255, 500, 10.0, stall_s=0.5)
        assert abs(st.position - 100) <= 2 and st.detection is Detection.AT_POSITION
        assert not dev.moving(dev.status())


def test_halt_from_another_thread_ends_the_wait_as_aborted_never_done() -> None:
    with device("can") as (server, dev):
        dev.calibrate(30.0)
        outcome: list[BaseException | None] = []

        def slow_open() -> None:
            try:
                dev.go("move", 0, 0, 500, 60.0, stall_s=30.0)  # the slowest byte: seconds of device time
                outcome.append(None)
            except BaseException as exc:  # noqa: BLE001 - the test looks at it
                outcome.append(exc)

        with held(server, creep=MSG_CREEP_S) as clock:
            start = dev.status().position
            worker = threading.Thread(target=slow_open, daemon=True)
            worker.start()
            step_until(clock, lambda: dev.status().position != start, "the motion under way", step=0.1)
            assert dev.moving(dev.status())  # a wait runs: the bits are believed
            dev.halt()
        worker.join(10.0)
        assert len(outcome) == 1 and isinstance(outcome[0], CommandFailed)
        assert "aborted by stop()" in str(outcome[0])
