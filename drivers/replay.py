"""Replaying a captured session: the sans-IO core shared by both families' replay servers.

:class:`Script` is the capture as steps (one request, the answers that followed it and their delays), and
:meth:`Script.answer` decides what a new request gets. Rules, in order: the next request of the capture gets
its answers; a repeat of the request answered last gets the same answers again (a client polls a state a
varying number of times while a motion runs); requests of the capture that only repeat the one before them may
be skipped to reach a match (the client polled fewer times). Anything else is a mismatch: reported with both
requests, and not answered, so the test that runs against the replay fails instead of passing on answers
meant for another request.

The servers live beside their drivers: :mod:`grippers.drivers.wsg.sim.replay` (the WSG over TCP, from hex
dumps with directions as ``grippers monitor --proxy --write`` saves them) and
:mod:`grippers.drivers.stepfoc.sim.replay` (STEPFOC nodes on a CAN bus, from candump logs).
"""

from __future__ import annotations

import sys
from collections.abc import Hashable
from dataclasses import dataclass, field
from typing import Any


@dataclass
class Step:
    request: Hashable
    shown: str  # the request for people (hex, or a decoded line)
    answers: list[tuple[float, Any]] = field(default_factory=list)  # (seconds after the request, answer)


@dataclass(frozen=True)
class Mismatch:
    index: int  # the step expected next
    expected: str | None  # None: the capture has ended
    got: str

    def __str__(self) -> str:
        if self.expected is None:
            return f"request after the end of the capture: {self.got}"
        return f"request {self.index + 1} differs from the capture: expected {self.expected}, got {self.got}"


class Script:
    """The capture's steps and the position reached; pure (no clocks, no I/O)."""

    def __init__(self, steps: list[Step]) -> None:
        if not steps:
            raise ValueError("the capture holds no request")
        self.steps = steps
        self.next = 0
        self.last: Step | None = None
        self.answered = 0
        self.repeated = 0
        self.mismatches: list[Mismatch] = []

    def answer(self, request: Hashable, shown: str) -> list[tuple[float, Any]] | Mismatch:
        index = self.next
        while index < len(self.steps):
            step = self.steps[index]
            if step.request == request:
                self.next, self.last = index + 1, step
                self.answered += 1
                return step.answers
            repeats_previous = index > 0 and step.request == self.steps[index - 1].request
            if not repeats_previous:
                break
            index += 1  # a poll the client did not repeat as often this time
        if self.last is not None and self.last.request == request:
            self.repeated += 1
            return self.last.answers
        expected = self.steps[self.next].shown if self.next < len(self.steps) else None
        mismatch = Mismatch(self.next, expected, shown)
        self.mismatches.append(mismatch)
        return mismatch

    @property
    def done(self) -> bool:
        return self.next >= len(self.steps)


MAX_ANSWER_DELAY_S = 3600.0  # no device answers an hour after a request: a capture saying so is damaged


def relative(steps: list[Step]) -> list[Step]:
    """Answer times as seconds after their request (the first entry of each step holds the request's time).

    A gap beyond :data:`MAX_ANSWER_DELAY_S` is a ValueError (the CLI's one line, exit 2), not a timer of
    1e300 s that died with a traceback in its thread while the replay served on (issue 43 §6)."""
    for step in steps:
        t0 = step.answers[0][0]
        step.answers = [(max(0.0, t - t0), a) for t, a in step.answers[1:]]
        late = next((d for d, _ in step.answers if not d <= MAX_ANSWER_DELAY_S), None)
        if late is not None:
            raise ValueError(
                f"an answer {late:.6g} s after its request ({step.shown}): a capture's answers come within "
                f"{MAX_ANSWER_DELAY_S:g} s"
            )
    return steps


def report(mismatch: Mismatch, stream: Any = None) -> None:
    print(f"grippers sim: replay: {mismatch}; not answered", file=stream or sys.stderr, flush=True)


def summary(script: Script) -> str:
    left = len(script.steps) - script.next
    return (
        f"grippers sim: replay: {script.answered} request(s) answered, {script.repeated} repeated, "
        f"{len(script.mismatches)} mismatch(es), {left} of {len(script.steps)} not reached"
    )
