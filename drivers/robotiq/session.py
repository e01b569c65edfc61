"""The rules of a Robotiq exchange sequence, sans-IO: when a motion has ended, what a fault means for a wait.

Kept apart from the backend so every face (threaded, a future asyncio or remote one) applies the same rules to
the status it reads; nothing here does I/O or keeps time itself (``now`` is passed in).
"""

from __future__ import annotations

import enum
from dataclasses import dataclass, field

from .registers import MAJOR_FAULTS, Fault, ObjectDetection, Status

START_S = 0.2  # a motion not seen moving after this long has ended (the SDK waits 200 ms for a start)
END_COUNTS = 3  # gPO this close to the target's end position: the fingers are there


class FaultClass(enum.Enum):
    NONE = "none"
    TRANSIENT = "transient"  # 0x05 action delayed, 0x09 watchdog note: a wait goes on
    NOT_ACTIVATED = "not_activated"  # 0x07: rACT must be set first
    MINOR = "minor"  # 0x08 temperature: clears by itself, the motion is over
    MAJOR = "major"  # 0x0A-0x0F: a reset (rACT 0 then 1) is needed


def classify_fault(code: int) -> FaultClass:
    if code == Fault.NONE:
        return FaultClass.NONE
    if code in (Fault.ACTION_DELAYED, Fault.NO_COMMUNICATION):
        return FaultClass.TRANSIENT
    if code == Fault.ACTIVATION_BIT:
        return FaultClass.NOT_ACTIVATED
    return FaultClass.MAJOR if code in MAJOR_FAULTS else FaultClass.MINOR


@dataclass
class MotionTracker:
    """One go-to: rPR ``position`` written at ``sent_at``; :meth:`update` says when the motion has ended.

    The echo (gPR) says a status belongs to this request (manual, "position request echo"). gOBJ may still
    carry the previous motion's end for a cycle, so an end counts once the fingers were seen moving, or stand
    at this target (``open_count``..``closed_count`` bound where they can stop), or after ``start_s``.
    """

    position: int
    sent_at: float
    open_count: int = 0
    closed_count: int = 255
    start_s: float = START_S
    end_counts: int = END_COUNTS
    seen_moving: bool = field(default=False, init=False)

    def update(self, st: Status, now: float) -> bool:
        if st.position_echo != self.position:
            return False
        if st.obj == ObjectDetection.MOVING:
            self.seen_moving = True
            return False
        end = min(max(self.position, self.open_count), self.closed_count)
        return (
            self.seen_moving
            or abs(st.position - end) <= self.end_counts
            or now - self.sent_at >= self.start_s
        )
