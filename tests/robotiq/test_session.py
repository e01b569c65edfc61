"""The sans-IO rules: when a motion has ended, and what each fault means for a wait."""

from __future__ import annotations

from grippers.drivers.robotiq.registers import ActivationState, Fault, ObjectDetection, Status
from grippers.drivers.robotiq.session import FaultClass, MotionTracker, classify_fault


def _st(obj: int, echo: int, pos: int) -> Status:
    return Status(True, True, ActivationState.COMPLETE, ObjectDetection(obj), 0, 0, echo, pos, 0)


def test_an_end_counts_only_for_this_request_and_once_it_started() -> None:
    t = MotionTracker(230, sent_at=0.0, open_count=3, closed_count=230)
    assert not t.update(_st(3, 0, 3), 0.01)  # the previous request's status
    assert not t.update(_st(3, 230, 3), 0.02)  # this request, but gOBJ not yet updated
    assert not t.update(_st(0, 230, 100), 0.03)
    assert t.update(_st(2, 230, 150), 0.04)  # contact after moving: the end
    assert MotionTracker(0, 0.0, 3, 230).update(_st(3, 0, 4), 0.0)  # already there (rPR 0 stops at 3)
    assert MotionTracker(230, 0.0, 3, 230).update(_st(2, 230, 50), 0.25)  # never seen moving: START_S passed


def test_fault_classes() -> None:
    assert classify_fault(0) is FaultClass.NONE
    assert classify_fault(Fault.ACTION_DELAYED) is FaultClass.TRANSIENT
    assert classify_fault(Fault.NO_COMMUNICATION) is FaultClass.TRANSIENT
    assert classify_fault(Fault.ACTIVATION_BIT) is FaultClass.NOT_ACTIVATED
    assert classify_fault(Fault.TEMPERATURE) is FaultClass.MINOR
    assert {classify_fault(c) for c in range(0x0A, 0x10)} == {FaultClass.MAJOR}
