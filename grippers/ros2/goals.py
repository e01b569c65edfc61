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

Each step starts under the :class:`Arbiter`'s lock after checking that its goal is still the current one,
so a goal that was preempted or cancelled between two steps can never send its next step after the newer
command: the library's own rule (the newer motion wins) then holds across steps too.
"""

from __future__ import annotations

import math
import threading
from collections.abc import Callable
from dataclasses import dataclass
from typing import Any, TypeVar

from ..gripper import GraspResult, GraspState, Gripper, GripperState
from ..motions import MotionHandle

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
            return call()


def _started(value: object) -> MotionHandle[Any]:
    """The handle of a motion started with ``wait=False`` (the Gripper's return type covers both forms)."""
    assert isinstance(value, MotionHandle)
    return value


def effort_of(state: GripperState) -> float:
    return float(state.force) if state.force is not None else math.nan


class GoalRunner:
    """Runs one goal's steps with feedback while the jaws move."""

    def __init__(
        self,
        gripper: Gripper,
        arbiter: Arbiter,
        ticket: Ticket,
        *,
        feedback: Callable[[], Any],
        period: float,
        tolerance: float = DEFAULT_TOLERANCE,
    ) -> None:
        self.gripper = gripper
        self.arbiter = arbiter
        self.ticket = ticket
        self.feedback = feedback
        self.period = period
        self.tolerance = tolerance

    def _step(self, call: Callable[[], MotionHandle[T]]) -> T:
        handle = self.arbiter.start(self.ticket, call)
        ended = threading.Event()
        handle.add_done_callback(lambda _h: ended.set())
        while not ended.wait(self.period):
            self.feedback()
        self.feedback()
        return handle.wait(0)

    def _settled(self, target: float) -> Outcome:
        st = self.gripper.state()
        return Outcome(st.width, effort_of(st), False, abs(st.width - target) <= self.tolerance)

    def run(self, width: float, speed: float | None, force: float | None) -> Outcome:
        """Execute a goal already checked against the limits (``Gripper.check``)."""
        g = self.gripper
        now = g.state()
        if width >= now.width - self.tolerance:
            if now.grasp is GraspState.HOLDING:
                self._step(lambda: _started(g.release(width, speed, wait=False)))
            else:
                self._step(lambda: _started(g.move(width, speed, wait=False)))
            return self._settled(width)
        result: GraspResult = self._step(lambda: _started(g.grasp(width, speed, force, wait=False)))
        if not result.grasped and result.width > width + self.tolerance:
            found = result.width  # stopped short of the target without holding: a part outside the window
            result = self._step(lambda: _started(g.grasp(found, speed, force, wait=False)))
        if result.grasped:
            effort = result.force if result.force is not None else effort_of(g.state())
            return Outcome(result.width, effort, True, abs(result.width - width) <= self.tolerance)
        if result.width <= width + self.tolerance:
            # Nothing between the jaws: they closed past the target by the grasp's travel; go back to it.
            self._step(lambda: _started(g.move(width, speed, wait=False)))
            return self._settled(width)
        raise GoalFailed(
            f"no part held at {result.width * 1000:.1f} mm: {result.reason or result.state.value}",
            self._settled(width),
        )
