"""The Gripper holds a Device and is put together from small collaborators (issue 28 item 1, issue 32).

In-process devices, no transport: the optional ``liveness`` and ``state_source`` features the zenoh client
needs, ``fast_stop_shared``, the ``DeviceGripper`` alias, and the size rule (no class over ~400 lines by its
whole MRO) for the Gripper and the remote client built on it.
"""

from __future__ import annotations

import inspect
import time
from collections.abc import Callable
from typing import Any

import pytest

from grippers.device import Device, Liveness, StateSource
from grippers.device_gripper import DeviceGripper
from grippers.errors import ConnectionLost, FastStopActive, GripperError
from grippers.gripper import Gripper
from grippers.profiles import load_profile
from grippers.states import DeviceInfo, GraspResult, GraspState, GripperState, MotionResult
from grippers.streams import QueuedStream


def _state(width: float = 0.05, faults: tuple[str, ...] = ()) -> GripperState:
    return GripperState(width, 0.0, 0.0, None, GraspState.IDLE, False, True, faults, time.time())


class _Device(Device):
    reports_fast_stop = True

    def __init__(self) -> None:
        self.faults: tuple[str, ...] = ()
        self.reads = 0

    def home(self, timeout: float) -> None:
        return None

    def move(self, width: float, speed: float, timeout: float) -> MotionResult:
        return MotionResult(width, GraspState.IDLE)

    def grasp(self, width: float, speed: float, force: float, timeout: float) -> GraspResult:
        return GraspResult(True, width, force, GraspState.HOLDING)

    def stop(self) -> None:
        return None

    def read_state(self) -> GripperState:
        self.reads += 1
        return _state(faults=self.faults)

    def info(self) -> DeviceInfo:
        raise GripperError("no info here", device=self.name, command="info")

    def close(self) -> None:
        return None


class _Liveness:
    def __init__(self) -> None:
        self.error: GripperError | None = None
        self.listeners: list[Callable[[bool], Any]] = []

    def add_listener(self, callback: Callable[[bool], Any]) -> Callable[[], None]:
        self.listeners.append(callback)
        return lambda: self.listeners.remove(callback)

    def lose(self) -> None:
        self.error = ConnectionLost("the server withdrew it", device="test")
        for fn in list(self.listeners):
            fn(False)


class _Pushed(QueuedStream):
    def __init__(self, on_close: Callable[[Any], None]) -> None:
        super().__init__(0.01, 8)
        self.on_close = on_close

    def close(self) -> None:
        self._stop.set()
        self.on_close(self)


class _Source:
    def __init__(self) -> None:
        self.opened: list[_Pushed] = []

    def subscribe(
        self, rate_hz: float, callback: Callable[[GripperState], Any] | None, on_close: Callable[[Any], None]
    ) -> _Pushed:
        s = _Pushed(on_close)
        self.opened.append(s)
        return s


def _gripper(device: Device) -> Gripper:
    return Gripper(device, load_profile("wsg50"), "test://x", timeout=1.0)


def test_device_gripper_is_an_alias_of_gripper() -> None:
    assert DeviceGripper is Gripper
    from grippers import device_gripper

    assert "alias" in (device_gripper.__doc__ or "")


def test_a_device_liveness_is_the_grippers_connection() -> None:
    device = _Device()
    device.liveness = live = _Liveness()
    assert isinstance(live, Liveness)
    g = _gripper(device)
    told: list[bool] = []
    g.on_connection(told.append)
    assert g.connected
    live.lose()
    assert not g.connected
    with pytest.raises(ConnectionLost, match="withdrew"):
        g.move(0.05)
    with pytest.raises(ConnectionLost):
        g.state()
    g.close()
    assert told == [False]  # told once: at the loss, not again at close()


def test_a_device_state_source_feeds_stream_and_close_ends_it() -> None:
    device = _Device()
    device.state_source = source = _Source()
    assert isinstance(source, StateSource)
    g = _gripper(device)
    s = g.stream(10.0)
    assert source.opened == [s] and device.reads == 0  # pushed, not polled
    g.close()
    assert s._stop.is_set()


def test_a_shared_fast_stop_is_read_again_before_a_motion_is_refused() -> None:
    device = _Device()
    device.fast_stop_shared = True
    g = _gripper(device)
    device.faults = ("fast_stop",)
    g.state()
    with pytest.raises(FastStopActive):
        g.move(0.05)
    device.faults = ()  # another client acknowledged it
    assert g.move(0.05).width == pytest.approx(0.05)  # type: ignore[union-attr]
    g.close()


def test_an_unshared_fast_stop_stays_latched_until_acknowledge() -> None:
    device = _Device()
    device.reports_fast_stop = False
    g = _gripper(device)
    g.fast_stop()
    reads = device.reads
    with pytest.raises(FastStopActive):
        g.move(0.05)
    assert device.reads == reads  # nothing read: the latch is the gripper's
    assert "fast_stop" in g.state().faults
    g.acknowledge()
    g.move(0.05)
    g.close()


def _mro_lines(cls: type) -> int:
    return sum(len(inspect.getsourcelines(c)[0]) for c in cls.__mro__ if c.__module__.startswith("grippers"))


@pytest.mark.parametrize("name", ["grippers.gripper:Gripper", "grippers.remote.client:RemoteGripper"])
def test_the_gripper_stays_under_400_lines_by_its_whole_mro(name: str) -> None:
    module, _, attr = name.partition(":")
    if "remote" in module:
        pytest.importorskip("zenoh")
    cls = getattr(__import__(module, fromlist=[attr]), attr)
    assert _mro_lines(cls) <= 400


def test_the_remote_device_and_its_link_stay_under_400_lines() -> None:
    pytest.importorskip("zenoh")
    from grippers.remote.client import RemoteDevice
    from grippers.remote.link import ServedLink

    assert _mro_lines(RemoteDevice) <= 400 and _mro_lines(ServedLink) <= 400
