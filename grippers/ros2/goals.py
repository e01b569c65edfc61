"""What a GripperCommand goal does to a :class:`~grippers.Gripper`: plain Python, no rclpy.

The ROS 2 node (:mod:`grippers.ros2.node`) maps messages onto this and back; keeping the semantics here
means they read in one place and hold whatever carries the goal.

A GripperCommand's ``position`` is a target for the jaws, not the width of a part, while the WSG's
``grasp(width)`` wants the part's nominal width and reports "no part" when the jaws stop outside its
clamping window (WSG manual 4.0.x §3.2.6). So a closing goal is run as:

1. ``grasp(position, force)``: the device's own force-limited grasp. On an MSG it closes towards the target
   at the force's current and holds whatever stops it (STEPFOC detection 1); on a WSG it holds a part within
   the clamping travel of ``position``.
2. If the jaws stopped short of the target without holding (a WSG meeting a part wider than the window: the
   fingers rest on the part with the force limit set in step 1), ``grasp(width where they stopped)``: the
   part's nominal width is now known, and the device's grasp logic holds it.
3. If the jaws closed past the target with nothing between them (no part), ``move(position)`` brings them
   back to the target: a goal without a part ends where it asked, like a move.

A goal at or beyond the current width (within the tolerance) opens: ``release`` when a part is held (the
device's own way to let go), ``move`` otherwise.

A plain move (opening, or step 3) that something stops is *stalled*, as ros2_controllers' gripper controller
means it: the device says so (the library's ``MotionBlocked``, a CommandFailed carrying ``.width``; a WSG's
E_AXIS_BLOCKED), the move ends short of its target, or the jaws move slower than ``stall_velocity_threshold``
for ``stall_timeout`` while short of it (a device that reports nothing for a blocked move; the jaws are then
stopped). Whether a stalled goal succeeds is the node's rule (``allow_stalling``), not this module's.

Each step starts under the :class:`Arbiter`'s lock after checking that its goal is still the current one,
so a goal that was preempted or cancelled between two steps can never send its next step after the newer
command: the library's own rule (the newer motion wins) then holds across steps too.
"""

from __future__ import annotations

import math
import threading
import time
from collections.abc import Callable
from dataclasses import dataclass
from typing import Any, TypeVar

from ..errors import CommandFailed
from ..gripper import GraspResult, GraspState, Gripper, GripperState
from ..motions import MotionHandle
from ..units import to_mm

T = TypeVar("T")

# m: "reached the target"; an MSG's position byte is ~0.4 mm on msg-150 (105 mm stroke)
DEFAULT_TOLERANCE = 0.001


@dataclass(frozen=True)
class Outcome:
    """The result fields of GripperCommand: measured width (m), force (N, NaN when unknown), flags."""

    position: float
    effort: float
    stalled: bool
    reached_goal: bool


class GoalEnded(Exception):
    """The goal was ended from outside (cancelled, preempted, node shutting down) before a step started."""


class GoalFailed(Exception):
    """The goal ended without doing what it asked (no part held): aborted, with the measured outcome."""

    def __init__(self, message: str, outcome: Outcome) -> None:
        super().__init__(message)
        self.outcome = outcome


class Ticket:
    """One command's right to start motions; ended once a newer command (or a cancel) takes over."""

    def __init__(self, name: str) -> None:
        self.name = name
        self.ended: str | None = None  # why, once ended

    def __repr__(self) -> str:
        return f"<Ticket {self.name} {'ended: ' + self.ended if self.ended else 'current'}>"


class Arbiter:
    """Orders commands from several ROS callbacks: the newest one owns the gripper.

    ``begin()`` ends the current ticket and hands out a new one; ``start()`` starts a motion only for the
    current ticket, under the same lock, so an older goal cannot slip a step in after a newer one began.
    """

    def __init__(self) -> None:
        self._lock = threading.Lock()
        self._current: Ticket | None = None
        self._motions = threading.Lock()  # a leaf lock: held for the two fields below, never around a call
        self._moving = 0  # motions started and not ended yet
        self._settled_at = 0.0  # time.monotonic() when the last one ended

    def begin(self, name: str, why: str) -> Ticket:
        with self._lock:
            if self._current is not None and self._current.ended is None:
                self._current.ended = why
            self._current = Ticket(name)
            return self._current

    def end(self, ticket: Ticket, why: str) -> bool:
        """End ``ticket`` if it still runs (a cancel); True when it was the current one."""
        with self._lock:
            if ticket.ended is not None:
                return False
            ticket.ended = why
            return ticket is self._current

    def end_all(self, why: str) -> bool:
        """End the current ticket, if any; True when one was running (a goal or ~/home)."""
        with self._lock:
            if self._current is not None and self._current.ended is None:
                self._current.ended = why
                return True
            return False

    def start(self, ticket: Ticket, call: Callable[[], MotionHandle[T]]) -> MotionHandle[T]:
        with self._lock:
            if ticket.ended is not None:
                raise GoalEnded(ticket.ended)
            with self._motions:
                self._moving += 1  # before the call: no instant where it runs uncounted
            try:
                handle = call()
            except BaseException:
                self._motion_ended(None)
                raise
        # A handle's callbacks may run at once, or inside a later call that ends it (a newer motion, a stop,
        # possibly under this lock or the gripper's own): _motion_ended takes only its own leaf lock.
        handle.add_done_callback(self._motion_ended)
        return handle

    def _motion_ended(self, _handle: object) -> None:
        with self._motions:
            self._moving -= 1
            self._settled_at = time.monotonic()

    def at_rest_since(self) -> float | None:
        """When the last motion started here ended (monotonic), or None while one runs: a state read that
        began after it shows where that motion left the jaws."""
        with self._motions:
            return None if self._moving else self._settled_at

    def check(self, ticket: Ticket) -> None:
        """GoalEnded if ``ticket`` was ended (a goal that needs no motion still honours a cancel)."""
        with self._lock:
            if ticket.ended is not None:
                raise GoalEnded(ticket.ended)

    def if_current(self, ticket: Ticket, call: Callable[[], object]) -> bool:
        """Run ``call`` (a stop) only while ``ticket`` is current: never stop a newer goal's motion."""
        with self._lock:
            if ticket is not self._current:
                return False
            call()
            return True


def _started(value: object) -> MotionHandle[Any]:
    """The handle of a motion started with ``wait=False`` (the Gripper's return type covers both forms)."""
    assert isinstance(value, MotionHandle)
    return value


def effort_of(state: GripperState) -> float:
    return float(state.force) if state.force is not None else math.nan


def blocked_width(exc: CommandFailed) -> float | None | bool:
    """Whether a failed move was stopped by an obstacle: the width where the jaws stopped (the library's
    ``MotionBlocked`` carries it), True when blocked at an unknown width, False when it failed otherwise.

    Read by name and attribute, not by class: ``grippers.MotionBlocked`` (issue 31) may not exist in the
    library this runs with, and a WSG before it says E_AXIS_BLOCKED in a plain CommandFailed."""
    width = getattr(exc, "width", None)
    if isinstance(width, int | float) and not isinstance(width, bool) and math.isfinite(width):
        return float(width)
    return type(exc).__name__ == "MotionBlocked" or "E_AXIS_BLOCKED" in str(exc)


@dataclass(frozen=True)
class StallRule:
    """ros2_controllers' stall rule: short of the target and slower than ``velocity`` for ``timeout`` s."""

    tolerance: float = DEFAULT_TOLERANCE
    velocity: float = 0.001  # m/s
    timeout: float = 1.0  # s


class _StallWatch:
    def __init__(self, rule: StallRule, target: float) -> None:
        self.rule, self.target = rule, target
        self.last: tuple[float, float] | None = None  # (time, width) of the previous sample
        self.moved_at = time.monotonic()

    def stalled(self, st: GripperState) -> bool:
        now = time.monotonic()
        last = self.last
        if (
            last is not None
            and now > last[0]
            and abs(st.width - last[1]) / (now - last[0]) > self.rule.velocity
        ):
            self.moved_at = now
        self.last = (now, st.width)
        if abs(st.width - self.target) <= self.rule.tolerance:
            self.moved_at = now
            return False
        return now - self.moved_at > self.rule.timeout


class _Stalled(Exception):
    pass


class GoalRunner:
    """Runs one goal's steps, reading the state every ``period`` for feedback (and the stall rule)."""

    max_age = 0.05  # s: how old the last published state may be to decide a goal on (see _now)

    def __init__(
        self,
        gripper: Gripper,
        arbiter: Arbiter,
        ticket: Ticket,
        *,
        feedback: Callable[[GripperState], Any],
        period: float,
        rule: StallRule | None = None,
        recent: Callable[[], tuple[GripperState, float] | None] | None = None,
    ) -> None:
        self.gripper = gripper
        self.arbiter = arbiter
        self.ticket = ticket
        self.feedback = feedback
        self.period = period
        self.rule = rule or StallRule()
        self.tolerance = self.rule.tolerance
        self.recent = recent  # the last published state and when its read began (monotonic)

    def _now(self) -> GripperState:
        """The jaws' state for the goal's decision: the state joint_states read last, when that read began
        after the last motion started here ended and within ``max_age``; a read of its own otherwise."""
        recent = self.recent() if self.recent is not None else None
        rest = self.arbiter.at_rest_since()
        if recent is not None and rest is not None:
            st, read_at = recent
            if rest < read_at and time.monotonic() - read_at <= self.max_age:
                return st
        return self.gripper.state()

    def _read(self) -> GripperState | None:
        try:
            return self.gripper.state()
        except Exception:  # noqa: BLE001 - the step's own result reports a device that stopped answering
            return None

    def _step(self, call: Callable[[], MotionHandle[T]], watch_target: float | None = None) -> T:
        handle = self.arbiter.start(self.ticket, call)
        ended = threading.Event()
        handle.add_done_callback(lambda _h: ended.set())
        watch = None if watch_target is None else _StallWatch(self.rule, watch_target)
        while not ended.wait(self.period):
            st = self._read()
            if st is None:
                continue
            if self.ticket.ended is None:
                self.feedback(st)
            if watch is not None and watch.stalled(st):
                self.arbiter.if_current(self.ticket, self.gripper.stop)
                ended.wait(max(1.0, 10 * self.period))  # the stopped motion's handle ends (bounded)
                raise _Stalled()
        st = self._read()
        if st is not None and self.ticket.ended is None:
            self.feedback(st)
        return handle.wait(0)

    def _settled(self, target: float, stalled: bool = False) -> Outcome:
        st = self.gripper.state()
        reached = abs(st.width - target) <= self.tolerance
        # a move that ended short of its target was stopped by something: stalled
        return Outcome(st.width, effort_of(st), stalled or not reached, reached)

    def _move(self, call: Callable[[], MotionHandle[Any]], target: float) -> Outcome:
        try:
            self._step(call, watch_target=target)
        except _Stalled:
            return self._settled(target, stalled=True)
        except CommandFailed as exc:
            where = blocked_width(exc)
            if where is False:
                raise
            out = self._settled(target, stalled=True)
            if isinstance(where, float) and not isinstance(where, bool):
                out = Outcome(where, out.effort, True, abs(where - target) <= self.tolerance)
            return out
        return self._settled(target)

    def run(self, width: float, speed: float | None, force: float | None) -> Outcome:
        """Execute a goal already checked against the limits (``Gripper.check``)."""
        g = self.gripper
        now = g.state()
        if (
            not now.moving
            and now.grasp is not GraspState.HOLDING
            and abs(now.width - width) <= self.tolerance
        ):
            # Already there and at rest: nothing to send (a move to where the jaws are would only cost a
            # device exchange and state reads; docs/performance.md, target 14). A newer goal still ends an
            # older one: begin() has ended its ticket, and the jaws do not move.
            self.arbiter.check(self.ticket)
            return Outcome(now.width, effort_of(now), False, True)
        if width >= now.width - self.tolerance:
            if now.grasp is GraspState.HOLDING:
                return self._move(lambda: _started(g.release(width, speed, wait=False)), width)
            return self._move(lambda: _started(g.move(width, speed, wait=False)), width)
        result: GraspResult = self._step(lambda: _started(g.grasp(width, speed, force, wait=False)))
        if not result.grasped and result.width > width + self.tolerance:
            found = result.width  # stopped short of the target without holding: a part outside the window
            result = self._step(lambda: _started(g.grasp(found, speed, force, wait=False)))
        if result.grasped:
            effort = result.force if result.force is not None else effort_of(g.state())
            return Outcome(result.width, effort, True, abs(result.width - width) <= self.tolerance)
        if result.width <= width + self.tolerance:
            # Nothing between the jaws: they closed past the target by the grasp's travel; go back to it.
            return self._move(lambda: _started(g.move(width, speed, wait=False)), width)
        raise GoalFailed(
            f"no part held at {to_mm(result.width):.1f} mm: {result.reason or result.state.value}",
            self._settled(width),
        )
