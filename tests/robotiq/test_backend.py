"""``grippers.open("sim://robotiq-…")`` end to end: activation, motions, grasps, stops, every fault as a typed
error, the transports (TCP forwarder, the pty's RTU line), the slave id, and lost or corrupt replies."""

from __future__ import annotations

import time
from collections.abc import Callable, Iterator
from typing import Any

import pytest

import grippers
from grippers import MotionBlocked, NotReferenced
from grippers.backends.robotiq import RobotiqFault, fault_error
from grippers.drivers.robotiq.registers import MAJOR_FAULTS, ActivationState, Command, Fault
from grippers.errors import CommandFailed, FastStopActive, GripperTimeout, URLError
from grippers.gripper import GraspState


def _until(check: Callable[[], bool], seconds: float = 10.0) -> None:
    deadline = time.monotonic() + seconds
    while not check():
        assert time.monotonic() < deadline, "condition not reached"
        time.sleep(0.01)


@pytest.fixture(params=["tcp", "pty", "urcap"])
def g(request: pytest.FixtureRequest) -> Iterator[Any]:
    gripper = grippers.open(f"sim://robotiq-2f85?time_scale=10&transport={request.param}")
    try:
        yield gripper
    finally:
        gripper.close()
        assert gripper.simulator.error is None


def test_a_motion_before_activation_is_a_clear_error_then_home_activates(g: Any) -> None:
    assert not g.state().referenced
    with pytest.raises(NotReferenced, match="not activated.*home"):
        g.move(0.04)
    g.simulator.pause()
    handle = g.home(wait=False)
    _until(lambda: g.simulator.model.sta == ActivationState.IN_PROGRESS)
    assert not g.state().referenced  # "activation in progress" is reported, not completion
    g.simulator.resume()
    handle.wait(10)
    assert g.state().referenced and abs(g.state().width - 0.085) < 1e-3


def test_home_on_an_active_gripper_toggles_nothing(g: Any) -> None:
    g.home()
    g.move(0.03)
    writes = g.simulator.model.writes
    g.home()
    assert g.simulator.model.writes == writes  # a status read, no rACT toggle
    assert abs(g.state().width - 0.03) < 1e-3


def test_moves_grasps_and_release(g: Any) -> None:
    g.home()
    r = g.move(0.05, 0.15)
    assert abs(r.width - 0.05) < 0.5e-3 and r.state is GraspState.IDLE
    miss = g.grasp(0.03)
    assert (
        not miss.grasped
        and miss.state is GraspState.NO_PART
        and "without meeting a part" in (miss.reason or "")
    )
    g.release()
    with g.simulator.lock:
        g.simulator.model.part_width_mm = 42.0
    hit = g.grasp(0.04, force=60)
    assert hit.grasped and abs(hit.width - 0.042) < 0.5e-3 and g.state().grasp is GraspState.HOLDING
    with g.simulator.lock:
        g.simulator.model.part_width_mm = None
    _until(lambda: g.state().grasp is GraspState.PART_LOST)
    assert abs(g.release().width - 0.085) < 1e-3


def test_a_plain_move_stopped_by_a_part_says_where(g: Any) -> None:
    g.home()
    with g.simulator.lock:
        g.simulator.model.part_width_mm = 50.0
    with pytest.raises(MotionBlocked) as err:
        g.move(0.02)
    assert isinstance(err.value, CommandFailed) and abs(err.value.width - 0.050) < 0.5e-3


def test_stop_and_fast_stop_end_the_motion_honestly(g: Any) -> None:
    g.home()
    g.simulator.pause()
    handle = g.move(0.0, 0.02, wait=False)
    _until(lambda: g.state().moving)
    g.stop()
    with pytest.raises(CommandFailed, match="aborted by stop"):
        handle.wait(5)
    assert not g.simulator.model.gto
    handle = g.move(0.0, 0.02, wait=False)
    _until(lambda: g.state().moving)
    g.fast_stop()
    with pytest.raises(CommandFailed, match="aborted by fast_stop"):
        handle.wait(5)
    assert "fast_stop" in g.state().faults  # latched by the library: the device has no fast-stop state
    with pytest.raises(FastStopActive):
        g.move(0.04)
    g.acknowledge()
    g.simulator.resume()
    assert g.state().faults == () and abs(g.move(0.04).width - 0.04) < 1e-3


@pytest.mark.parametrize(
    "code", [0x08, *sorted(MAJOR_FAULTS - {Fault.AUTO_RELEASE_IN_PROGRESS, Fault.AUTO_RELEASE_COMPLETE})]
)
def test_every_fault_during_a_motion_is_a_typed_error_naming_it(g: Any, code: int) -> None:
    g.home()
    g.simulator.pause()
    handle = g.move(0.0, 0.02, wait=False)
    _until(lambda: g.state().moving)
    with g.simulator.lock:
        g.simulator.model.inject_fault(code)
    with pytest.raises(RobotiqFault) as err:
        handle.wait(5)
    assert err.value.status == code and f"0x{code:02X}" in str(err.value) and g.url in str(err.value)
    g.simulator.resume()
    if code in MAJOR_FAULTS:
        assert g.state().grasp is GraspState.ERROR
        with pytest.raises(RobotiqFault):
            g.move(0.04)
        g.acknowledge()  # the reset (rACT 0): the fault is cleared, nothing moves
        assert not g.state().referenced and g.state().faults == ()
        g.home()  # the activation, which sweeps the fingers
    else:
        with g.simulator.lock:
            g.simulator.model.clear_fault()
    assert g.state().referenced and g.state().faults == ()
    assert abs(g.move(0.04).width - 0.04) < 1e-3


def test_automatic_release_faults_are_reported_and_acknowledged(g: Any) -> None:
    g.home()
    g.driver.write_command(Command(act=True, atr=True, ard=True))
    _until(lambda: "automatic_release_completed" in g.state().faults)
    with pytest.raises(RobotiqFault, match="automatic release completed"):
        g.move(0.04)
    g.acknowledge()
    assert not g.state().referenced and g.state().faults == ()
    g.home()
    assert g.state().referenced


def test_servo_streams_position_requests(g: Any) -> None:
    g.home()
    for w in (0.08, 0.06, 0.04):
        g.servo(w, 0.15)
    _until(lambda: abs(g.state().width - 0.04) < 1e-3)
    g.stop()
    assert g.servo_stats.sent >= 1


def test_slave_id_and_a_silent_or_corrupt_device() -> None:
    with grippers.open("sim://robotiq-hande?slave=3&timeout=0.5") as g:
        assert g.driver.slave == 3 and g.info().extra["slave"] == 3
        g.simulator.faults.silent = True
        with pytest.raises(GripperTimeout, match="no answer from slave 3"):
            g.state()
        g.simulator.faults.silent = False
        g.simulator.faults.corrupt_replies(1)  # a bad CRC: dropped in silence, so the read times out
        with pytest.raises(GripperTimeout):
            g.state()
        g.simulator.faults.send_garbage(b"\x09\x03\x06\xff")
        assert g.state().width > 0  # garbage before a reply: resynchronised


def test_profiles_and_urls_are_checked() -> None:
    from grippers.profiles import load_profile

    for name, stroke in (("robotiq-2f85", 0.085), ("robotiq-2f140", 0.140), ("robotiq-hande", 0.050)):
        assert abs(load_profile(name).limits().max_width - stroke) < 1e-9
    with pytest.raises(URLError, match="slave"):
        grippers.open("sim://robotiq-2f85?slave=300")
    with pytest.raises(URLError):
        grippers.open("robotiq+udp://127.0.0.1:1")


def test_reconnect_after_the_forwarder_dropped_the_connection() -> None:
    with grippers.open("sim://robotiq-2f85?activated=true&reconnect=true&timeout=0.5") as g:
        assert abs(g.move(0.05).width - 0.05) < 1e-3
        first = g.driver
        g.simulator.faults.request_close()
        _until(lambda: g.driver is not first and g.connected)
        assert abs(g.move(0.03).width - 0.03) < 1e-3


def test_the_gripper_sim_fixture_serves_a_robotiq(gripper_sim: Any) -> None:
    url = gripper_sim("robotiq-2f140", part_width_mm=60, activated=True)
    with grippers.open(url) as g:
        assert g.profile.name == "robotiq-2f140"
        r = g.grasp(0.06)
        assert r.grasped and abs(r.width - 0.060) < 1e-3


def test_the_asyncio_face_drives_a_robotiq() -> None:
    import asyncio

    import grippers.aio

    async def main() -> float:
        g = await grippers.aio.open("sim://robotiq-2f85?activated=true&time_scale=10")
        try:
            await g.move(0.04)
            return (await g.state()).width
        finally:
            await g.close()

    assert abs(asyncio.run(main()) - 0.04) < 1e-3


class _ScriptedClient:
    """Answers status reads from a script, as a device whose gOBJ lags the write by a cycle."""

    slave = 9
    alive = True

    def __init__(self, statuses: list[tuple[int, int, int]]) -> None:
        self.statuses = statuses  # (gOBJ, gPR, gPO) after the write
        self.written: list[Command] = []

    def read_status(self, *, command: str = "") -> Any:
        from grippers.drivers.robotiq.registers import ObjectDetection, Status

        obj, echo, pos = self.statuses.pop(0) if self.written and len(self.statuses) > 1 else self.statuses[0]
        return Status(
            True, bool(self.written), ActivationState.COMPLETE, ObjectDetection(obj), 0, 0, echo, pos, 0
        )

    def write_command(self, cmd: Command, *, command: str = "") -> None:
        self.written.append(cmd)

    def close(self) -> None:
        pass


def test_a_stale_gobj_after_the_write_is_not_taken_for_the_end_of_the_motion() -> None:
    from grippers.backends.robotiq import robotiq_gripper
    from grippers.profiles import load_profile

    # Before: open (gPO 3); then the first status still says "at position" at gPO 3, then moving, then there.
    client = _ScriptedClient([(3, 0, 3), (3, 230, 3), (0, 230, 120), (3, 230, 230)])
    profile = load_profile("robotiq-2f85")
    g = robotiq_gripper(client, profile, "robotiq+serial:///dev/scripted", timeout=0.5)  # type: ignore[arg-type]
    try:
        assert g.move(0.0).width < 1e-3  # not 85 mm, which the stale status claimed
    finally:
        g.close()


@pytest.mark.parametrize("code", range(1, 16))
def test_every_gflt_code_maps_to_one_typed_outcome(code: int) -> None:
    from grippers.backends.robotiq import robotiq_gripper
    from grippers.drivers.robotiq.registers import FAULT_NAMES, ObjectDetection, Status
    from grippers.profiles import load_profile

    g = robotiq_gripper(
        _ScriptedClient([(3, 0, 3)]),  # type: ignore[arg-type]
        load_profile("robotiq-2f85"),  # type: ignore[arg-type]
        "robotiq+serial:///dev/scripted",
        timeout=0.5,
    )
    st = Status(True, True, ActivationState.COMPLETE, ObjectDetection.MOVING, code, 0, 0, 3, 0)
    err = fault_error(st, device=g.name, command="move")
    if code in (Fault.ACTION_DELAYED, Fault.NO_COMMUNICATION):
        assert err is None  # transient: the wait goes on
    elif code == Fault.ACTIVATION_BIT:
        assert isinstance(err, NotReferenced)
    else:
        assert isinstance(err, RobotiqFault) and err.status == code and err.command == "move"
        assert (err.status_name in FAULT_NAMES.values()) == (code in FAULT_NAMES)
    g.close()


@pytest.mark.parametrize("transport", ["tcp", "urcap"])
def test_home_after_an_activation_that_timed_out_waits_for_it(transport: str) -> None:
    """Issue 43 §5: the second home() found the activation under way, cleared rACT and never set it again,
    then failed "rACT was cleared (another program?)" and left the gripper reset."""
    with grippers.open(f"sim://robotiq-2f85?transport={transport}") as g:
        g.simulator.pause()  # the activation cannot complete: the first home() times out for sure
        with pytest.raises(GripperTimeout):
            g.home(timeout=0.3)
        g.simulator.resume()
        g.home(timeout=10)
        assert g.state().referenced and g.simulator.model.act


def test_stop_on_a_gripper_never_activated_writes_nothing() -> None:
    """Issue 40 §5: stop() wrote rACT 1, which started the activation's sweep of the whole stroke."""
    with grippers.open("sim://robotiq-2f85") as g:
        g.simulator.pause()
        for call in (g.stop, g.fast_stop, g.acknowledge):
            call()
        assert g.simulator.model.writes == 0 and not g.simulator.model.act
        g.simulator.step(3.0)
        assert not g.state().referenced and not g.state().moving


def test_a_fault_says_what_to_run_in_the_user_s_terms(g: Any) -> None:
    """Issue 39 §2: the next step is the command line's, ``grippers ack URL``, not a Python method name."""
    g.home()
    with g.simulator.lock:
        g.simulator.model.inject_fault(Fault.OVERCURRENT)
    with pytest.raises(RobotiqFault) as err:
        g.move(0.04)
    assert f"`grippers ack {g.url}`" in str(err.value) and f"`grippers home {g.url}`" in str(err.value)
