"""Hypothesis strategies of the STEPFOC tests that more than one file draws from."""

from __future__ import annotations

from hypothesis import strategies as st

from grippers.drivers.stepfoc.can_protocol import Detection

# Every field of a 60 status frame (GripperStatus) but the identifier's error bit, which is not in the data.
STATUS_FIELDS = {
    "position": st.integers(0, 255),
    "current_ma": st.integers(-32768, 32767),
    "activated": st.booleans(),
    "action": st.booleans(),
    "detection": st.sampled_from(Detection),
    "temperature_error": st.booleans(),
    "timeout_error": st.booleans(),
    "estop_error": st.booleans(),
    "calibrated": st.booleans(),
}
