"""The backend conformance suite: the promises every family keeps, checked on a simulator through the public
API only (``grippers.open``, the ``Gripper`` methods, ``MotionHandle``, ``state()``, ``info()``, the errors).

A backend's own test suite subclasses :class:`ConformanceSuite` and names its simulator::

    from grippers.testing.conformance import ConformanceSuite

    class TestAcmeConformance(ConformanceSuite):
        target = "acme-1"  # a profile name, or "sim://acme-1?transport=pty" with sim:// settings

Several families or transports: parametrise the class over ``conformance_target``, one line each::

    @pytest.mark.parametrize("conformance_target", ["sim://wsg50", "sim://msg-150?transport=pty"])
    class TestMyFamilies(ConformanceSuite):
        pass

The simulator is started as the ``gripper_sim`` fixture starts it (``backend.simulator(profile, settings)``),
so a family needs only what ``gripper_sim`` needs; optional simulator features widen what is checked, and a
check that needs one the simulator lacks is skipped with the reason: ``part_width_mm`` (grasps with and
without a part) and fault hooks ``simulator.faults.silent`` (a device that stops answering: typed timeout,
reconnection).

Timing does not depend on the machine's load: where a check needs the jaws still moving when it acts, the
simulator runs at a clock slow enough that a crossing of the stroke at minimum speed lasts
:attr:`ConformanceSuite.hold_wall_s` (10 s of wall time) and the check waits until ``state().moving`` before
it acts; the step that needs the motion running takes milliseconds. (A paused simulator clock would stand the
device still while the client's own wall-clock timers run on, which a backend detecting stalls would rightly
report as a stall.) Everything else runs the simulator ``time_scale`` times faster than real time
(:attr:`ConformanceSuite.time_scale`, or the target's own ``time_scale``). Every wait has a bound.
"""

from __future__ import annotations

import math
import threading
import time
from collections.abc import Callable, Iterator
from dataclasses import dataclass, field
from typing import Any, TypeVar

import pytest

import grippers
from grippers import (
    CommandFailed,
    ConnectionLost,
    FastStopActive,
    GraspState,
    GripperError,
    GripperTimeout,
    LimitError,
    URLError,
)
from grippers.drivers.urls import scheme_of
from grippers.motions import MotionHandle
from grippers.units import to_m, to_mm
from grippers.urls import parse_url, with_params

from . import GripperSims, SimURL

__all__ = ["Conformance", "ConformanceSuite", "Target"]

T = TypeVar("T")

# Reconnection settings for the reconnection check: a silent device noticed within a second, retried often.
RECONNECT_QUERY = {
    "reconnect": "true",
    "heartbeat_s": "0.1",
    "reconnect_backoff_s": "0.05",
    "reconnect_backoff_max_s": "0.2",
}


@dataclass(frozen=True)
class Target:
    """What the suite simulates: a profile name and ``sim://`` settings (``"sim://wsg50?transport=udp"``)."""

    profile: str
    settings: dict[str, str] = field(default_factory=dict)

    @classmethod
    def parse(cls, text: str) -> Target:
        url = parse_url(text if scheme_of(text) == "sim" else f"sim://{text}")  # the one URL grammar
        if not url.profile:
            raise URLError(f"conformance target {text!r}: no profile name (sim://NAME?setting=value)")
        return cls(url.profile, url.params)

    def __str__(self) -> str:
        base = f"sim://{self.profile}"
        return with_params(base, **self.settings) if self.settings else base


class Conformance:
    """One check's simulators and grippers (the ``conformance`` fixture): everything started is closed after
    the check, and a simulator whose thread died fails it, as with ``gripper_sim``."""

    def __init__(self, target: Target, *, time_scale: float, hold_wall_s: float, tolerance: float) -> None:
        self.target = target
        self.time_scale = float(target.settings.get("time_scale", time_scale))
        self.hold_wall_s = hold_wall_s
        self.tolerance = tolerance
        self.sims = GripperSims()
        self.grippers: list[grippers.Gripper] = []
        profile = grippers.load_profile(target.profile)
        m = profile.mechanics
        crossing_s = 0.9 * m.stroke_mm / max(m.min_speed_mm_s, 1e-6)  # seconds of device time at min speed
        self.hold_time_scale = min(self.time_scale, crossing_s / hold_wall_s)

    # -- starting ----------------------------------------------------------------------------------------

    def simulator(self, *, hold: bool = False, part_m: float | None = None, **settings: Any) -> SimURL:
        """Start the target's simulator: at the slow clock when ``hold``, with a part ``part_m`` wide."""
        given: dict[str, Any] = {**self.target.settings, **settings}
        given["time_scale"] = self.hold_time_scale if hold else self.time_scale
        if part_m is not None:
            given["part_width_mm"] = round(to_mm(part_m), 1)
            try:
                return self.sims(self.target.profile, **given)
            except URLError as exc:
                if "part_width_mm" in str(exc):
                    pytest.skip(f"{self.target}: the simulator takes no part_width_mm setting ({exc})")
                raise
        return self.sims(self.target.profile, **given)

    def open(self, url: str, **query: str) -> grippers.Gripper:
        """``grippers.open`` on a simulator's URL (plus ``query``), closed after the check."""
        if query:
            # still served in this process, which grippers.open must know (its timeout)
            url = SimURL.serving(with_params(url, **query), getattr(url, "simulator", None))
        g = grippers.open(url)
        self.grippers.append(g)
        return g

    def homed(self, *, hold: bool = False, part_m: float | None = None) -> grippers.Gripper:
        """A gripper on a fresh simulator, homed (referenced or calibrated) and ready to move."""
        g = self.open(self.simulator(hold=hold, part_m=part_m))
        g.home()
        return g

    # -- observing ---------------------------------------------------------------------------------------

    @staticmethod
    def until(what: str, predicate: Callable[[], T | None], bound: float = 10.0) -> T:
        """Poll observable state until ``predicate()`` is truthy; fails naming ``what`` after ``bound`` s."""
        deadline = time.monotonic() + bound
        while not (value := predicate()):
            if time.monotonic() > deadline:
                pytest.fail(f"{what}: not within {bound:g} s", pytrace=False)
            time.sleep(0.005)
        return value

    def until_still(self, g: grippers.Gripper) -> grippers.GripperState:
        def still() -> grippers.GripperState | None:
            st = g.state()
            return None if st.moving else st

        return self.until("the jaws come to rest", still)

    def long_motion(self, g: grippers.Gripper) -> tuple[MotionHandle[Any], float, float]:
        """Start a move across the stroke at minimum speed on a ``hold`` simulator and wait until the device
        reports it moving: (handle, width at the start, target)."""
        lo, hi = g.limits.min_width, g.limits.max_width
        start = g.state().width
        target = lo + 0.05 * (hi - lo) if start > (lo + hi) / 2 else hi - 0.05 * (hi - lo)
        handle = g.move(target, g.limits.min_speed, wait=False)
        assert isinstance(handle, MotionHandle), "move(wait=False) must return a MotionHandle"
        self.until("state().moving after move(wait=False)", lambda: g.state().moving or handle.done())
        assert not handle.done(), f"the slow move ended at once: {handle}"
        return handle, start, target

    def close(self) -> list[str]:
        problems = []
        for g in self.grippers:
            try:
                g.close()
            except Exception as exc:  # noqa: BLE001 - reported with the simulators' problems
                problems.append(f"{g.name}: close() raised {exc!r}")
        self.grippers.clear()
        return problems + self.sims.close()


def _raises_typed(
    expected: type[BaseException], why: str, call: Callable[..., object], *args: Any
) -> BaseException:
    """``call(*args)`` must raise ``expected``, a GripperError; anything else, or nothing, fails (``why``)."""
    try:
        outcome = call(*args)
    except expected as exc:
        assert isinstance(exc, GripperError), f"{why}: {type(exc).__name__} is not a GripperError"
        return exc
    except BaseException as exc:  # noqa: BLE001 - the wrong type is the finding
        pytest.fail(f"{why}: raised {type(exc).__name__}: {exc}, not {expected.__name__}", pytrace=False)
    pytest.fail(f"{why}: returned {outcome!r} instead of raising {expected.__name__}", pytrace=False)


def _done(outcome: T | MotionHandle[T]) -> T:
    """The result of a blocking motion call (``wait=True`` returns it, never a handle)."""
    assert not isinstance(outcome, MotionHandle), f"a blocking call returned a handle: {outcome}"
    return outcome


def _bad_values(kind: str, lo: float, hi: float) -> object:
    return {
        "below": lo - max(abs(lo), 1.0) if lo <= 0 else lo / 2,
        "above": hi * 2 + 1.0,
        "nan": math.nan,
        "inf": math.inf,
        "text": str(round((lo + hi) / 2, 4)),
    }[kind]


class ConformanceSuite:
    """The checks. Subclass it with ``target`` set (or parametrise ``conformance_target``); override the
    class attributes only where a device's documented accuracy needs it."""

    target: str = ""
    time_scale: float = 20.0  # the simulator's speed-up for checks that do not hold the jaws moving
    hold_wall_s: float = 10.0  # wall seconds a minimum-speed crossing lasts where a check holds a motion
    tolerance: float = 0.002  # m: a completed motion's reported width against its target
    motion_bound_s: float = 30.0  # wall seconds any one motion of a check may take
    settle_s: float = 3.0  # device seconds a check waits for what must not happen (an activation, a homing)

    @pytest.fixture
    def conformance_target(self) -> str:
        if not self.target:
            pytest.fail(f"{type(self).__name__}: set `target`, or parametrise conformance_target", False)
        return self.target

    @pytest.fixture
    def conformance(self, conformance_target: str) -> Iterator[Conformance]:
        c = Conformance(
            Target.parse(str(conformance_target)),
            time_scale=self.time_scale,
            hold_wall_s=self.hold_wall_s,
            tolerance=self.tolerance,
        )
        try:
            yield c
        finally:
            problems = c.close()
        if problems:
            pytest.fail("; ".join(problems), pytrace=False)

    # -- limits ------------------------------------------------------------------------------------------

    @pytest.mark.parametrize("kind", ["below", "above", "nan", "inf", "text"])
    def test_a_bad_value_is_refused_before_anything_is_sent(
        self, conformance: Conformance, kind: str
    ) -> None:
        """LimitError for a width, speed or force out of range, NaN, infinite or text, from every motion
        command, with or without ``wait``; the device does not move and its grasp state is unchanged."""
        g = conformance.homed()
        lim = g.limits
        before = g.state()
        width = _bad_values(kind, lim.min_width, lim.max_width)
        speed = _bad_values(kind, lim.min_speed, lim.max_speed)
        force = _bad_values(kind, lim.min_force, lim.max_force)
        w, s, f = (lim.min_width + lim.max_width) / 2, lim.max_speed, lim.min_force
        calls: dict[str, Callable[[bool], object]] = {
            f"move(width={width!r})": lambda wait: g.move(width, wait=wait),  # type: ignore[arg-type]
            f"move(speed={speed!r})": lambda wait: g.move(w, speed, wait=wait),  # type: ignore[arg-type]
            f"grasp(width={width!r})": lambda wait: g.grasp(width, s, f, wait=wait),  # type: ignore[arg-type]
            f"grasp(speed={speed!r})": lambda wait: g.grasp(w, speed, f, wait=wait),  # type: ignore[arg-type]
            f"grasp(force={force!r})": lambda wait: g.grasp(w, s, force, wait=wait),  # type: ignore[arg-type]
            f"release(width={width!r})": lambda wait: g.release(width, wait=wait),  # type: ignore[arg-type]
            f"release(speed={speed!r})": lambda wait: g.release(w, speed, wait=wait),  # type: ignore[arg-type]
        }
        for name, call in calls.items():
            for wait in (False, True):
                _raises_typed(LimitError, f"{name}, wait={wait}", call, wait)
        after = g.state()
        assert not after.moving, f"the device moves after refused commands: {after}"
        assert abs(after.width - before.width) < conformance.tolerance, (before, after)
        assert after.grasp == before.grasp, (before, after)

    # -- motions end honestly ----------------------------------------------------------------------------

    def test_a_completed_move_reports_its_width(self, conformance: Conformance) -> None:
        g = conformance.homed()
        lo, hi, tol = g.limits.min_width, g.limits.max_width, conformance.tolerance
        for fraction in (0.3, 0.7):
            target = lo + fraction * (hi - lo)
            result = _done(g.move(target, timeout=self.motion_bound_s))
            assert abs(result.width - target) < tol, f"move to {target} reported {result}"
            state = conformance.until_still(g)
            assert abs(state.width - target) < tol, f"move to {target}: state {state}"
        handle = g.move(lo + 0.5 * (hi - lo), wait=False)
        assert isinstance(handle, MotionHandle)
        result = handle.wait(self.motion_bound_s)
        assert handle.done() and abs(result.width - (lo + 0.5 * (hi - lo))) < tol, result

    @pytest.mark.parametrize("how", ["stop", "cancel"])
    def test_a_stopped_motion_is_reported_stopped_never_done(
        self, conformance: Conformance, how: str
    ) -> None:
        """``stop()`` during a move, or ``cancel()`` of its handle: the handle raises CommandFailed naming
        the call, and the jaws rest on the way (not at the target)."""
        g = conformance.homed(hold=True)
        handle, start, target = conformance.long_motion(g)
        (handle.cancel if how == "cancel" else g.stop)()
        exc = _raises_typed(CommandFailed, f"a move ended by {how}()", handle.wait, self.motion_bound_s)
        assert f"{how}()" in str(exc) and "superseded" not in str(exc), f"after {how}(): {exc}"
        assert handle.done()
        state = conformance.until_still(g)
        assert abs(state.width - target) > conformance.tolerance, f"stopped, yet at the target: {state}"

    def test_stop_ends_a_blocking_motion_in_another_thread(self, conformance: Conformance) -> None:
        g = conformance.homed(hold=True)
        lo, hi = g.limits.min_width, g.limits.max_width
        target = lo if g.state().width > (lo + hi) / 2 else hi
        outcome: list[object] = []

        def run() -> None:
            try:
                outcome.append(g.move(target, g.limits.min_speed, timeout=self.motion_bound_s * 4))
            except BaseException as exc:  # noqa: BLE001 - the outcome is what is checked
                outcome.append(exc)

        thread = threading.Thread(target=run, name="conformance-blocking-move", daemon=True)
        thread.start()
        conformance.until("state().moving during a blocking move", lambda: g.state().moving or outcome)
        g.stop()
        thread.join(self.motion_bound_s)
        assert not thread.is_alive(), "the blocking move did not return after stop()"
        assert len(outcome) == 1 and isinstance(outcome[0], CommandFailed), outcome
        assert "stop()" in str(outcome[0]), outcome[0]

    def test_the_newer_motion_wins(self, conformance: Conformance) -> None:
        """A motion started while another runs supersedes it: the older handle raises CommandFailed
        "superseded by move ..." at once (settled when the newer call returns) and never returns the newer
        motion's result; the newer one completes."""
        g = conformance.homed(hold=True)
        older, start, _ = conformance.long_motion(g)
        lo, hi = g.limits.min_width, g.limits.max_width
        middle = (lo + hi) / 2
        newer = g.move(middle, g.limits.max_speed, wait=False)
        assert isinstance(newer, MotionHandle)
        assert older.done(), "the older motion's handle is still open once the newer motion was started"
        exc = _raises_typed(CommandFailed, "the superseded motion's handle", older.wait, 0)
        assert "superseded by move" in str(exc), f"the older motion ended with {exc!r}, not as superseded"
        result = newer.wait(self.motion_bound_s)
        assert abs(result.width - middle) < conformance.tolerance, f"the newer move reported {result}"

    def test_state_is_readable_while_a_motion_runs(self, conformance: Conformance) -> None:
        g = conformance.homed(hold=True)
        handle, start, target = conformance.long_motion(g)
        low, high = min(start, target), max(start, target)
        slack = conformance.tolerance
        states = [g.state() for _ in range(5)]
        assert not handle.done(), "the held motion ended while its state was read"
        for st in states:
            assert isinstance(st, grippers.GripperState)
            assert st.moving, f"state() during a motion says it is not moving: {st}"
            assert low - slack <= st.width <= high + slack, f"width {st.width} outside {low}..{high}: {st}"
        assert g.info().limits == g.limits, "info() during a motion"
        g.stop()
        _raises_typed(CommandFailed, "the motion ended by stop()", handle.wait, self.motion_bound_s)

    # -- typed errors ------------------------------------------------------------------------------------

    def test_errors_are_typed(self, conformance: Conformance) -> None:
        """A motion before homing, a misspelt setting and a device that stops answering each raise their
        GripperError subclass (a silent device within a bounded time)."""
        url = conformance.simulator()
        _raises_typed(URLError, "a misspelt setting", lambda: conformance.open(url, speling_mistake="1"))
        g = conformance.open(url)
        needs_home = {grippers.Capability.HOMING, grippers.Capability.CALIBRATION} & g.capabilities
        if needs_home:
            not_referenced = getattr(grippers, "NotReferenced", CommandFailed)
            lo, hi = g.limits.min_width, g.limits.max_width
            _raises_typed(not_referenced, "move() before home()", g.move, (lo + hi) / 2)
        faults = getattr(url.simulator, "faults", None)
        if faults is None or not hasattr(faults, "silent"):
            pytest.skip(f"{conformance.target}: the simulator has no faults.silent hook (a silent device)")
        faults.silent = True
        started = time.monotonic()
        _raises_typed(GripperTimeout, "state() of a silent device", g.state)
        bound = 3 * g.timeout + 2.0
        assert time.monotonic() - started < bound, f"state() of a silent device took over {bound:g} s"
        faults.silent = False

    # -- close -------------------------------------------------------------------------------------------

    def test_close_releases_everything(self, conformance: Conformance) -> None:
        """After close() no thread of the gripper is left, every call raises GripperError, a second close()
        is harmless, and the same URL opens again (nothing left bound)."""
        url = conformance.simulator()
        before = set(threading.enumerate())
        g = conformance.open(url)
        g.home()
        stream = g.stream(rate_hz=50)
        next(iter(stream))
        g.close()
        conformance.until(
            "every thread the gripper started has ended after close()",
            lambda: not [t for t in threading.enumerate() if t not in before and t.is_alive()],
            bound=2.0,
        )
        mid = (g.limits.min_width + g.limits.max_width) / 2
        for name, call in {
            "state()": g.state,
            "info()": g.info,
            "home()": g.home,
            "move()": lambda: g.move(mid),
            "grasp()": lambda: g.grasp(mid),
            "release()": g.release,
            "stop()": g.stop,
        }.items():
            _raises_typed(GripperError, f"{name} after close()", call)
        g.close()
        again = conformance.open(url)
        assert isinstance(again.state(), grippers.GripperState), "the same URL after close()"
        again.close()

    # -- grasps ------------------------------------------------------------------------------------------

    def test_a_grasp_on_a_part_reports_grasped(self, conformance: Conformance) -> None:
        profile = grippers.load_profile(conformance.target.profile)
        part = to_m(0.4 * profile.mechanics.stroke_mm)
        g = conformance.homed(part_m=part)
        force = (g.limits.min_force + g.limits.max_force) / 2
        result = _done(g.grasp(part, force=force, timeout=self.motion_bound_s))
        assert result.grasped, f"a grasp on a {to_mm(part):g} mm part: {result}"
        assert abs(result.width - part) < conformance.tolerance, result
        assert g.state().grasp is GraspState.HOLDING, g.state()
        g.release(timeout=self.motion_bound_s)
        assert g.state().grasp is not GraspState.HOLDING, g.state()

    def test_a_move_blocked_by_a_part_is_reported_blocked_never_done(self, conformance: Conformance) -> None:
        """A plain move() that a part stops short of its target raises MotionBlocked (a CommandFailed),
        never a result as if it had arrived."""
        blocked = getattr(grippers, "MotionBlocked", CommandFailed)
        part = to_m(0.4 * grippers.load_profile(conformance.target.profile).mechanics.stroke_mm)
        g = conformance.homed(part_m=part)
        g.release(timeout=self.motion_bound_s)
        lim = g.limits
        target = lim.min_width + 0.1 * (lim.max_width - lim.min_width)
        exc = _raises_typed(blocked, f"move to {target:g} m across a {part:g} m part", g.move, target)
        assert "superseded" not in str(exc), exc
        state = conformance.until_still(g)
        assert state.width > target + conformance.tolerance, f"the jaws passed the part: {state}"

    def test_a_grasp_without_a_part_reports_not_grasped(self, conformance: Conformance) -> None:
        g = conformance.homed()
        lim = g.limits
        width = lim.min_width + 0.4 * (lim.max_width - lim.min_width)
        try:
            result = _done(g.grasp(width, timeout=self.motion_bound_s))
        except CommandFailed as exc:  # also honest: the device refused to call it a grasp
            assert "superseded" not in str(exc), exc
        else:
            assert not result.grasped, f"a grasp with nothing between the jaws reported grasped: {result}"
        assert g.state().grasp is not GraspState.HOLDING, g.state()

    # -- stops on a device at rest ----------------------------------------------------------------------

    @pytest.mark.parametrize("homed", [False, True], ids=["never-homed", "homed"])
    def test_stops_and_acknowledge_never_start_a_motion_on_a_device_at_rest(
        self, conformance: Conformance, homed: bool
    ) -> None:
        """Issue 40 §5: ``stop()``, ``fast_stop()`` and ``acknowledge()`` on a device that is not moving start
        nothing: no activation or homing (a Robotiq's rACT written to 1 sweeps the whole stroke), no motion.
        Each may refuse with a typed error; none may move the jaws or reference the device."""
        g = conformance.open(conformance.simulator())
        if homed:
            g.home()
        before = conformance.until_still(g)
        for name in ("stop", "fast_stop", "acknowledge"):
            try:
                getattr(g, name)()
            except grippers.NotSupported:
                pass
            except GripperError as exc:  # a typed refusal is honest (a device that must be homed first)
                assert not isinstance(exc, (GripperTimeout, ConnectionLost)), f"{name}(): {exc!r}"
        settle = max(self.settle_s / conformance.time_scale, 0.3)  # device seconds an activation would take
        deadline = time.monotonic() + settle
        while time.monotonic() < deadline:
            st = g.state()
            assert not st.moving, f"stop/fast_stop/acknowledge started a motion: {st}"
            assert st.referenced == before.referenced, f"the device was referenced by a stop: {st}"
            assert abs(st.width - before.width) < conformance.tolerance, f"the jaws moved: {before} -> {st}"
            time.sleep(0.01)

    # -- fast stop ---------------------------------------------------------------------------------------

    def test_fast_stop_aborts_and_acknowledge_clears_it(self, conformance: Conformance) -> None:
        g = conformance.homed(hold=True)
        offered = getattr(grippers.Capability, "FAST_STOP", None)
        if offered is not None and offered not in g.capabilities:
            pytest.skip(f"{conformance.target}: the device offers no fast stop (capabilities)")
        handle, _, target = conformance.long_motion(g)
        try:
            g.fast_stop()
        except grippers.NotSupported as exc:
            pytest.skip(f"{conformance.target}: fast_stop() is not supported: {exc}")
        aborted = _raises_typed(
            CommandFailed, "a move ended by fast_stop()", handle.wait, self.motion_bound_s
        )
        assert "fast_stop()" in str(aborted), aborted
        for _ in range(2):  # latched: a state read does not clear it (the gripper's latch, or the device's)
            assert g.state().fast_stopped, g.state()
        mid = (g.limits.min_width + g.limits.max_width) / 2
        _raises_typed(FastStopActive, "move() after fast_stop()", g.move, mid)
        _raises_typed(FastStopActive, "grasp() after fast_stop()", g.grasp, mid)
        _raises_typed(FastStopActive, "release() after fast_stop()", g.release)
        assert g.state().fast_stopped, g.state()
        g.acknowledge()
        assert not g.state().fast_stopped, g.state()
        result = _done(g.move(mid, g.limits.max_speed, timeout=self.motion_bound_s))
        assert abs(result.width - mid) < conformance.tolerance, result

    # -- reconnection ------------------------------------------------------------------------------------

    def test_reconnection_where_offered(self, conformance: Conformance) -> None:
        """With ``reconnect=true``, a device that falls silent is reported lost, calls raise ConnectionLost
        meanwhile, and it comes back by itself once it answers again."""
        url = conformance.simulator()
        faults = getattr(url.simulator, "faults", None)
        if faults is None or not hasattr(faults, "silent"):
            pytest.skip(f"{conformance.target}: the simulator has no faults.silent hook to drop the link")
        try:
            g = conformance.open(url, **RECONNECT_QUERY)
        except (URLError, grippers.NotSupported) as exc:
            pytest.skip(f"{conformance.target}: the backend offers no reconnection ({exc})")
        events: list[bool] = []
        g.on_connection(events.append)
        g.home()
        faults.silent = True
        conformance.until("the silent device reported lost (g.connected False)", lambda: not g.connected)
        _raises_typed(ConnectionLost, "state() during an outage", g.state)
        faults.silent = False
        # ``connected`` turns True before the listeners are told (a listener may call the gripper), so the
        # second event is waited for, not assumed (a busy CI run caught the gap).
        conformance.until("the link back and on_connection told", lambda: g.connected and len(events) >= 2)
        assert events[:2] == [False, True], events
        mid = (g.limits.min_width + g.limits.max_width) / 2
        try:
            result = _done(g.move(mid, timeout=self.motion_bound_s))
        except FastStopActive:  # a device that comes back in FAST STOP (the WSG after a dropped TCP link)
            g.acknowledge()
            result = _done(g.move(mid, timeout=self.motion_bound_s))
        assert abs(result.width - mid) < conformance.tolerance, result
