"""Issue 28 §1: what the device contract leaves to the gripper, checked on two real devices of the contract,
the Robotiq (built in) and the worked ACME R1 plugin, each over its simulator: both have no fast-stop state
of their own (``reports_fast_stop`` False) and take a new target mid-motion (``moves_to_new_targets``).

- the fast-stop latch is the gripper's: ``state().fast_stopped`` stays True over state reads, streams and
  the asyncio face until ``acknowledge()``, and every motion is refused with ``FastStopActive`` meanwhile,
  although the device itself reports no fast stop;
- a newer motion supersedes the running one without a stop written in between;
- a feature object the device leaves ``None`` is ``NotSupported``, with nothing sent;
- the polled-motion helper (``grippers.kit.motion.poll_until``) ends early, never as success.
"""

from __future__ import annotations

import asyncio
import time
from collections.abc import Callable, Iterator
from pathlib import Path
from typing import Any

import pytest

import grippers
import grippers.backends
from grippers import CommandFailed, ConnectionLost, FastStopActive, GripperTimeout, NotSupported
from grippers.device import DeviceContext
from grippers.kit.motion import MotionEpochs, poll_until

from ..cli.test_plugin_worked_example import _install  # the worked plugin installed as pip would

OPEN = {
    "robotiq": "sim://robotiq-2f85?activated=true&time_scale=10",
    "acme": "sim://acme-r1?time_scale=10",
}


def _until(what: str, check: Callable[[], object], seconds: float = 10.0) -> None:
    deadline = time.monotonic() + seconds
    while not check():
        assert time.monotonic() < deadline, f"{what}: not within {seconds:g} s"
        time.sleep(0.005)


@pytest.fixture(scope="module")
def acme_site(tmp_path_factory: pytest.TempPathFactory) -> Path:
    return _install(tmp_path_factory.mktemp("acme-r1-site"))


@pytest.fixture(params=sorted(OPEN))
def family(request: pytest.FixtureRequest, acme_site: Path, monkeypatch: pytest.MonkeyPatch) -> Iterator[str]:
    """Each device; the ACME plugin is installed for the test (by its entry points) and forgotten after it."""
    if request.param == "acme":
        monkeypatch.syspath_prepend(str(acme_site))
    yield request.param
    grippers.backends._cache.pop("acme", None)


@pytest.fixture
def g(family: str) -> Iterator[Any]:
    """A homed gripper on the family's simulator."""
    gripper = grippers.open(OPEN[family])
    try:
        gripper.home()
        yield gripper
    finally:
        gripper.close()
        assert gripper.simulator.error is None


def _slow_move(g: Any) -> Any:
    """A move across most of the stroke at minimum speed, on the simulator's paused clock: it stands still
    while the gripper reports it moving (nothing races the machine's load)."""
    _clock(g).pause()
    handle = g.move(g.limits.min_width + 0.1 * g.limits.stroke, g.limits.min_speed, wait=False)
    _until("the move reported moving", lambda: g.state().moving)
    return handle


def _clock(g: Any) -> Any:
    """What pauses the simulator: the Robotiq server itself, the ACME server's SimClock."""
    return g.simulator if g.info().family == "robotiq" else g.simulator.clock


def _resume(g: Any) -> None:
    _clock(g).resume()


def test_the_devices_declare_what_the_gripper_does_for_them(g: Any) -> None:
    assert g.device.reports_fast_stop is False and g.device.moves_to_new_targets is True
    assert isinstance(g, grippers.Gripper) and g.driver is g.device.driver


def test_the_gripper_keeps_the_fast_stop_latch_of_a_device_without_one(g: Any) -> None:
    handle = _slow_move(g)
    g.fast_stop()
    with pytest.raises(CommandFailed, match=r"fast_stop\(\)"):
        handle.wait(10)
    _resume(g)
    assert (
        not g.device.read_state().fast_stopped
    )  # the device has no fast-stop state: the latch is the gripper's
    for _ in range(3):  # a state read does not clear it, nor does the device's word
        assert g.state().fast_stopped and "fast_stop" in g.state().faults
    with g.stream(rate_hz=50) as stream:
        assert next(iter(stream)).fast_stopped
    mid = (g.limits.min_width + g.limits.max_width) / 2
    for name, call in {
        "move": lambda: g.move(mid),
        "grasp": lambda: g.grasp(mid),
        "release": lambda: g.release(),
        "home": lambda: g.home(),
        "move(wait=False)": lambda: g.move(mid, wait=False),
    }.items():
        with pytest.raises(FastStopActive, match="acknowledge"):
            call()
        assert g.state().fast_stopped, name
    g.acknowledge()
    assert not g.state().fast_stopped and "fast_stop" not in g.state().faults
    assert g.move(mid).width == pytest.approx(mid, abs=1e-3)


def test_the_asyncio_face_sees_the_same_latch(family: str) -> None:
    import grippers.aio

    async def main() -> tuple[bool, bool]:
        async with grippers.aio.open(OPEN[family]) as a:
            await a.home()
            await a.fast_stop()
            latched = (await a.state()).fast_stopped
            with pytest.raises(FastStopActive):
                await a.move((a.sync.limits.min_width + a.sync.limits.max_width) / 2)
            await a.acknowledge()
            return latched, (await a.state()).fast_stopped

    assert asyncio.run(main()) == (True, False)


def test_a_newer_motion_supersedes_without_a_stop(g: Any) -> None:
    """moves_to_new_targets: the older motion reports superseded, never done, and the newer one completes.
    On the Robotiq, whose simulator counts the request block's writes, the newer rPR is seen written over the
    running motion with rGTO set: one write, no stop (rGTO cleared) in between. (The ACME simulator keeps no
    such record: a stop and a GO look like a GO there.)"""
    robotiq = g.info().family == "robotiq"
    older = _slow_move(g)
    writes = g.simulator.model.writes if robotiq else 0
    target = g.limits.max_width - 0.1 * g.limits.stroke
    newer = g.move(target, g.limits.max_speed, wait=False)
    with pytest.raises(CommandFailed, match="superseded by move"):
        older.wait(10)
    if robotiq:
        model = g.simulator.model
        _until("the newer target written", lambda: model.command.position == g.profile.position_byte(target))
        assert model.writes == writes + 1 and model.command.gto  # one write, rGTO kept set: no stop
    else:
        _until("the newer target taken", lambda: g.simulator.model.target == pytest.approx(target * 1000))
    assert g.state().moving
    _resume(g)
    assert newer.wait(10).width == pytest.approx(target, abs=1e-3)


def test_a_feature_the_device_leaves_none_is_not_supported(g: Any, monkeypatch: pytest.MonkeyPatch) -> None:
    """Both offer a servo object, so servo() moves them; left None (a device without one), servo() is
    NotSupported and nothing is sent. Neither offers temperature, soft limits or a device tag."""
    g.servo(0.04, 0.15)
    _until("the servo target reached", lambda: abs(g.state().width - 0.04) < 1e-3)
    g.stop()
    monkeypatch.setattr(g.device, "servo", None)
    width = g.state().width
    with pytest.raises(NotSupported) as err:
        g.servo(0.06, 0.1)
    assert err.value.command == "servo" and g.name in str(err.value)
    assert g.state().width == pytest.approx(width, abs=1e-4) and not g.state().moving  # nothing was sent
    assert g.device.temperature is None and g.device.soft_limits is None and g.device.device_tag is None
    for call in (g.temperature, lambda: g.set_soft_limits(0.01, 0.05), g.device_tag):
        with pytest.raises(NotSupported):
            call()


# -- the polled-motion helper on its own -----------------------------------------------------------------


def _context(closed: Callable[[], bool] = lambda: False) -> DeviceContext:
    return DeviceContext(name="acme-r1@acme+tcp://test", closed=closed)


def test_poll_until_returns_the_status_that_ends_the_wait() -> None:
    reads = iter(range(10))
    assert (
        poll_until(lambda: next(reads), lambda n: n == 3, context=_context(), command="move", timeout=5) == 3
    )


def test_poll_until_ends_on_a_newer_epoch_never_as_success() -> None:
    epochs = MotionEpochs()
    motion = epochs.begin("superseded by a newer motion before it ended (move)")

    def read() -> int:
        epochs.begin("aborted by stop()")  # a stop while the status was read: that status is not the end
        return 1

    with pytest.raises(CommandFailed, match=r"move aborted by stop\(\)") as err:
        poll_until(
            read, lambda n: True, context=_context(), command="move", timeout=5, epochs=epochs, motion=motion
        )
    assert err.value.device == "acme-r1@acme+tcp://test" and err.value.status_name == "aborted"


def test_poll_until_ends_on_close_on_a_fault_and_at_the_timeout() -> None:
    closed = [False]
    reads: list[int] = []

    def read() -> int:
        reads.append(1)
        closed[0] = len(reads) >= 2
        return len(reads)

    with pytest.raises(ConnectionLost, match="closed"):
        poll_until(read, lambda n: False, context=_context(lambda: closed[0]), command="home", timeout=5)
    assert len(reads) == 2  # no read after the close was seen
    fault = CommandFailed("gripper fault 0x0B", device="d", command="grasp")
    with pytest.raises(CommandFailed, match="0x0B"):
        poll_until(
            lambda: 7, lambda n: True, context=_context(), command="grasp", timeout=5, fault=lambda n: fault
        )
    with pytest.raises(GripperTimeout, match="not done after 0.05 s") as err:
        poll_until(lambda: 0, lambda n: False, context=_context(), command="release", timeout=0.05)
    assert err.value.command == "release" and err.value.device == "acme-r1@acme+tcp://test"


def test_reconnect_true_is_refused_at_open_for_a_device_without_reconnection() -> None:
    """A device that leaves ``reconnection`` None: ``reconnect=true`` is NotSupported when it is switched on
    (grippers.open does it through grippers.reconnect.attach), not a watch that can never reconnect."""
    from grippers.backends.robotiq import robotiq_gripper
    from grippers.drivers.robotiq.client import RobotiqClient
    from grippers.reconnect import attach
    from grippers.settings import Settings

    with grippers.open(OPEN["robotiq"]) as served:
        host, port = served.url.removeprefix("robotiq+tcp://").split(":")
        client = RobotiqClient.tcp(host, int(port), device=served.url, timeout=0.5)
        g = robotiq_gripper(client, served.profile, served.url, timeout=0.5)  # no connector: no reconnection
        try:
            assert g.device.reconnection is None
            with pytest.raises(NotSupported, match="cannot reconnect"):
                attach(g, Settings(g.url, {"reconnect": "true"}, {}))
            assert g.connected and g.state().referenced  # nothing else changed
        finally:
            g.close()
        assert served.device.reconnection is not None  # the backend's own open offers it
