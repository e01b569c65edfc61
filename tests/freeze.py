"""Freezing a process (SIGSTOP) and knowing it is frozen before the test goes on.

``kill(pid, SIGSTOP)`` returns before the target's threads have stopped: each stops when it next runs, and
on a busy machine a server thread woken by the test's very next request could still answer it (seen: a
``state()`` right after SIGSTOP of ``grippers serve`` answered once). :func:`freeze` waits until Linux
reports every thread of the process stopped (``T`` in /proc/PID/task/TID/stat).
"""

from __future__ import annotations

import os
import signal
import subprocess
import time

FREEZE_TIMEOUT_S = 10.0


def _states(pid: int) -> list[str]:
    states = []
    for tid in os.listdir(f"/proc/{pid}/task"):
        try:
            with open(f"/proc/{pid}/task/{tid}/stat") as f:
                stat = f.read()
        except FileNotFoundError:  # a thread that just ended
            continue
        states.append(stat.rsplit(")", 1)[1].split()[0])  # the field after the command's closing paren
    return states


def freeze(proc: subprocess.Popen[str] | subprocess.Popen[bytes]) -> None:
    """SIGSTOP ``proc`` and return once every one of its threads is stopped; AssertionError if they are
    not within :data:`FREEZE_TIMEOUT_S`."""
    proc.send_signal(signal.SIGSTOP)
    deadline = time.monotonic() + FREEZE_TIMEOUT_S
    while time.monotonic() < deadline:
        states = _states(proc.pid)
        if states and all(s in ("T", "t") for s in states):
            return
        time.sleep(0.005)
    raise AssertionError(f"process {proc.pid} not stopped after SIGSTOP: thread states {_states(proc.pid)}")
