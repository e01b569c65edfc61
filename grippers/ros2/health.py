"""What one gripper's node says on ``/diagnostics``: plain Python over the node's own observations.

The node reads the device for joint_states anyway, so the diagnostics read nothing more: they summarise the
last state (and its age), the last read error, the connection as ``Gripper.connected`` says it, and counters
the node keeps. One ``DiagnosticStatus`` per gripper, named "NODE: gripper" (the convention of
diagnostic_updater's task names), ``hardware_id`` "VENDOR MODEL SERIAL".
"""

from __future__ import annotations

import collections
import threading
import time
from dataclasses import dataclass, field

from ..drivers.urls import without_secrets
from ..gripper import DeviceInfo, GripperState
from ..units import to_ms

OK, WARN, ERROR, STALE = 0, 1, 2, 3  # diagnostic_msgs/DiagnosticStatus levels (bytes on the wire)
# A WSG's "the last command failed" flag (a blocked move sets it): worth a WARN, not an ERROR.
_TRANSIENT = frozenset({"cmd_failure"})


@dataclass
class Health:
    """Observations and counters of one node; written from the executor's threads, read by its timer."""

    period: float = 1.0  # s between /diagnostics publications
    info: DeviceInfo | None = None
    url: str = ""
    state: GripperState | None = None
    state_at: float = 0.0  # time.monotonic() of the last state
    read_at: float = 0.0  # time.monotonic() when its read began
    read_error: str | None = None
    connected: bool = False
    temperature: float | None = None  # °C, where the device reports it (read once per publication)
    succeeded: int = 0
    aborted: int = 0
    cancelled: int = 0
    reconnects: int = 0
    _published: collections.deque[float] = field(default_factory=lambda: collections.deque(maxlen=1000))
    _lock: threading.Lock = field(default_factory=threading.Lock)

    def saw(self, st: GripperState, read_at: float) -> None:
        """A state read that began at ``read_at`` (monotonic) and was published."""
        now = time.monotonic()
        with self._lock:
            self.state, self.state_at, self.read_at, self.read_error = st, now, read_at, None
            self._published.append(now)

    def recent(self) -> tuple[GripperState, float] | None:
        """The last state and when its read began, for a goal's decision (GoalRunner._now)."""
        with self._lock:
            return None if self.state is None or self.read_error else (self.state, self.read_at)

    def failed(self, why: str) -> None:
        with self._lock:
            self.read_error = why

    def count(self, outcome: str) -> None:
        with self._lock:
            setattr(self, outcome, getattr(self, outcome) + 1)

    def rate(self, window: float = 2.0) -> float:
        now = time.monotonic()
        with self._lock:
            n = sum(1 for t in self._published if now - t <= window)
        return n / window

    def level(self) -> tuple[int, str]:
        """(level, message): ERROR beats STALE beats WARN."""
        with self._lock:
            st, age, error = self.state, time.monotonic() - self.state_at, self.read_error
        if not self.connected:
            return ERROR, "the connection is lost" if self.info is not None else "not open"
        if error is not None:
            return ERROR, error
        if st is not None and st.fast_stopped:
            return ERROR, "fast stop"
        faults = [f for f in st.faults if f not in _TRANSIENT] if st is not None else []
        if faults:
            return ERROR, "fault: " + ", ".join(faults)
        if st is None or age > 2 * self.period:
            return STALE, f"no state for {age:.1f} s" if st is not None else "no state yet"
        if not st.referenced:
            return WARN, "not referenced (call ~/home)"
        if st.faults:
            return WARN, "the last command failed"
        return OK, "ok"

    def values(self) -> list[tuple[str, str]]:
        info, st = self.info, self.state
        age = to_ms(time.monotonic() - self.state_at) if st is not None else float("nan")
        out = [
            ("family", info.family if info else ""),
            ("model", info.model if info else ""),
            ("firmware", (info.firmware or "") if info else ""),
            ("serial", (info.serial or "") if info else ""),
            ("url", without_secrets(self.url)),
            ("referenced", str(st.referenced).lower() if st else "unknown"),
            ("grasp state", st.grasp.value if st else "unknown"),
            ("faults", ", ".join(st.faults) if st else ""),
        ]
        if self.temperature is not None:
            out.append(("temperature", f"{self.temperature:g}"))
        out += [
            ("state age (ms)", f"{age:.0f}"),
            ("joint_states rate (Hz)", f"{self.rate():.1f}"),
            ("goals succeeded", str(self.succeeded)),
            ("goals aborted", str(self.aborted)),
            ("goals cancelled", str(self.cancelled)),
            ("reconnects", str(self.reconnects)),
        ]
        return out

    def hardware_id(self) -> str:
        info = self.info
        if info is None:
            return ""
        return " ".join(p for p in (info.vendor, info.model, info.serial or "") if p)
