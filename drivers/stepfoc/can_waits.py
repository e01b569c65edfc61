"""A CAN node's blocking waits: polls fed to the sans-IO trackers (motion.py), the one rule for an end.

Apart from :class:`~.can_client.StepfocNode`, whose methods are one frame each: these are the loops a direct
user of the node calls (``node.move(...)``, ``node.wait_motion()``, ``node.calibrate()``), and they read the
end of a motion exactly as :class:`~.device.StepfocDevice` does, through :class:`~.motion.MotionTracker` and
:class:`~.motion.CalibrationTracker`. Declared over :class:`PollingNode` so this module does not import the
client that calls it (issue 32: no import circles).
"""

from __future__ import annotations

import time
from collections.abc import Callable
from typing import Protocol

from ..errors import CommandFailed, GripperTimeout
from .can_protocol import GripperCommand, GripperStatus
from .motion import STALL_MIN_S, CalibrationTracker, MotionTracker, Reading, Verdict

__all__ = ["CalibrationWatch", "PollingNode", "poll_until", "wait_calibration", "wait_motion"]


class PollingNode(Protocol):
    """What a wait asks of its node (:class:`~.can_client.StepfocNode` provides it)."""

    @property
    def device(self) -> str: ...

    timeout: float
    last_command: GripperCommand | None

    def poll(self, timeout: float | None = None) -> GripperStatus: ...

    def fault(self, st: GripperStatus, timeout: float | None = None) -> str | None: ...


def _reading(st: GripperStatus) -> Reading:
    return Reading(st.position, int(st.detection), st.calibrated, st.current_ma)


def _failed(node: PollingNode, message: str, status: str, command: str) -> CommandFailed:
    return CommandFailed(message, status_name=status, device=node.device, command=command)


class CalibrationWatch:
    """Tells from successive 60 frames when a calibration the host started has ended: the sans-IO
    :class:`~grippers.drivers.stepfoc.motion.CalibrationTracker` with this client's clock."""

    def __init__(self, was_calibrated: bool) -> None:
        self.was_calibrated = was_calibrated
        self.tracker = CalibrationTracker(was_calibrated, time.monotonic())

    def update(self, st: GripperStatus) -> bool | str:
        """True when done, False while running, a reason (str) when the calibration ended without success."""
        verdict = self.tracker.update(_reading(st), time.monotonic())
        if verdict is Verdict.RETRY:
            return (
                "the calibrated bit dropped (the firmware's calibration time-out)"
                if self.was_calibrated and not st.calibrated
                else f"the jaws rest at position {st.position} without a completed calibration"
            )
        return verdict is Verdict.ENDED


def poll_until(
    node: PollingNode,
    ended: Callable[[GripperStatus, str | None], bool],
    timeout: float,
    poll_interval: float,
    late: str,
    command: str,
) -> GripperStatus:
    """Poll until ``ended(status, fault)`` is true (it raises for an end that is a failure); after
    ``timeout`` wall seconds, GripperTimeout saying ``late``. Every poll waits within the deadline."""
    deadline = time.monotonic() + timeout
    while True:
        st = node.poll(timeout=min(node.timeout, max(0.01, deadline - time.monotonic())))
        if ended(st, node.fault(st)):
            return st
        if time.monotonic() >= deadline:
            raise GripperTimeout(
                f"{late} after {timeout:g} s (position {st.position})", device=node.device, command=command
            )
        time.sleep(poll_interval)


def wait_motion(
    node: PollingNode, *, timeout: float, poll_interval: float, stall_s: float = STALL_MIN_S
) -> GripperStatus:
    """Poll until the node's last motion command has ended by :class:`MotionTracker`'s rule: detection 3
    only at its target byte, 1/2 once the jaws moved or it lasted. CommandFailed when the jaws stood still
    ``stall_s`` short of the target (idled or sent elsewhere by another host), when the action bit was
    cleared, or for a device error."""
    last = node.last_command
    if last is None:
        raise _failed(node, "no motion command was sent to wait for", "aborted", "move")
    tracker = MotionTracker(None, last.position, time.monotonic(), stall_s=stall_s, limit_ma=last.current_ma)

    def ended(st: GripperStatus, cause: str | None) -> bool:
        if cause is not None:
            raise _failed(node, f"motion aborted by a device error: {cause}", cause, "move")
        if not (st.activated and st.action):
            raise _failed(
                node,
                "motion aborted: the action bit was cleared (a stop, maybe from another host)",
                "aborted",
                "move",
            )
        verdict = tracker.update(_reading(st), time.monotonic())
        if verdict is Verdict.STALLED:
            raise _failed(
                node,
                f"motion aborted: the jaws stopped at position {st.position} short of {last.position}",
                "aborted",
                "move",
            )
        return verdict in (Verdict.ARRIVED, Verdict.OBJECT)

    return poll_until(node, ended, timeout, poll_interval, "still moving", "move")


def wait_calibration(
    node: PollingNode, was_calibrated: bool, *, timeout: float, poll_interval: float
) -> GripperStatus:
    """Poll (empty 61 frames, which do not abort it) until the calibration just started has ended."""
    watch = CalibrationWatch(was_calibrated)

    def ended(st: GripperStatus, cause: str | None) -> bool:
        if cause is not None:
            raise _failed(node, f"calibration refused or stopped: {cause}", cause, "calibrate")
        done = watch.update(st)
        if isinstance(done, str):
            raise _failed(node, f"calibration failed: {done}", "failed", "calibrate")
        return done

    return poll_until(node, ended, timeout, poll_interval, "calibration not finished", "calibrate")
