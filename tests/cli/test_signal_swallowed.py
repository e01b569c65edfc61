"""Issue 43: a signal CPython swallows is not lost, and a motion a signal stopped says which signal.

CPython reports an exception raised in a weakref callback or a ``__del__`` to ``sys.unraisablehook`` and goes
on. A SIGINT whose handler ran there (CI run CI6: the import system's module-lock callback, 0 ms after
``grippers monitor -`` started) was swallowed and the command ran on to exit 1 instead of 130. The rule of
grippers/cli/signals.py sends such a signal again, so it lands in ordinary code. The first test puts the
handler inside a weakref callback on purpose, which is exact where a timed signal is luck.
"""

from __future__ import annotations

import os
import signal
import subprocess
import sys
import threading
import time
from pathlib import Path
from typing import Any

import pytest

import grippers
from grippers.cli import signals
from grippers.errors import CommandFailed

from ..simhold import held

ROOT = Path(__file__).resolve().parents[2]

SIGNAL_IN_A_WEAKREF_CALLBACK = """
import signal, sys, time, weakref
from grippers.cli import signals

signals.like_ctrl_c()

class Part:
    pass

def callback(ref):
    signal.raise_signal(getattr(signal, sys.argv[1]))
    (lambda: None)()  # the handler runs at this call: inside the callback, where CPython swallows its raise

part = Part()
ref = weakref.ref(part, callback)
try:
    del part
    deadline = time.monotonic() + 10
    while time.monotonic() < deadline:  # a call in the body: python/cpython#130279 (3.13 lets a
        time.sleep(0.001)  # KeyboardInterrupt raised in a tight loop's condition past its try)
    print("ran on")
except KeyboardInterrupt as exc:
    print("interrupted", signals.exit_status(exc))
"""


@pytest.mark.parametrize("sig", ["SIGINT", "SIGTERM", "SIGHUP"])
def test_a_signal_swallowed_in_a_weakref_callback_is_taken_again(sig: str) -> None:
    proc = subprocess.run(
        [sys.executable, "-c", SIGNAL_IN_A_WEAKREF_CALLBACK, sig],
        cwd=ROOT,
        capture_output=True,
        text=True,
        timeout=60,
    )
    status = 128 + getattr(signal, sig)
    assert proc.stdout.strip() == f"interrupted {status}", proc.stdout + proc.stderr
    assert "Exception ignored" not in proc.stderr and "Traceback" not in proc.stderr, proc.stderr


def test_the_hook_is_put_back_and_other_unraisables_reach_it() -> None:
    if threading.current_thread() is not threading.main_thread():
        pytest.skip("signal handlers are set from the main thread only")
    before = sys.unraisablehook
    previous = signals.like_ctrl_c()
    try:
        assert sys.unraisablehook is not before
        seen: list[Any] = []
        signals._previous_hook = seen.append  # what was there before receives everything else
        sys.unraisablehook(type("U", (), {"exc_value": ValueError("x")})())
        assert len(seen) == 1
    finally:
        signals._previous_hook = before
        signals.restore(previous)
    assert sys.unraisablehook is before


def test_a_motion_stopped_by_sigterm_says_sigterm(gripper_sim: Any) -> None:
    if threading.current_thread() is not threading.main_thread():
        pytest.skip("signal handlers are set from the main thread only")
    url = gripper_sim("wsg50")
    previous = signals.like_ctrl_c()
    try:
        with grippers.open(url) as g:
            g.home()
            handles: list[Any] = []

            def terminate_once_running() -> None:
                deadline = time.monotonic() + 30
                while not handles and time.monotonic() < deadline:
                    handles.extend(h for h in list(g._motions.handles) if h.name == "move" and not h.done())
                    time.sleep(0.005)
                os.kill(os.getpid(), signal.SIGTERM)

            with held(url):  # the move cannot end before the signal
                sender = threading.Thread(target=terminate_once_running)
                sender.start()
                with pytest.raises(signals.Terminated):
                    g.move(0.02, 0.05)
                sender.join(30)
            assert handles, "the move never started"
            with pytest.raises(CommandFailed, match="aborted by SIGTERM"):
                handles[0].wait(0)
    finally:
        signals.restore(previous)


def test_main_puts_the_handlers_and_the_hook_back_after_a_usage_error() -> None:
    # main(argv) called in-process (tests, scripts): argparse's SystemExit left the rule in place before.
    from grippers.cli import main

    if threading.current_thread() is not threading.main_thread():
        pytest.skip("signal handlers are set from the main thread only")
    hook, handlers = sys.unraisablehook, {s: signal.getsignal(s) for s in signals.CAUGHT}
    with pytest.raises(SystemExit):
        main(["move", "--no-such-option"])
    assert sys.unraisablehook is hook
    assert {s: signal.getsignal(s) for s in signals.CAUGHT} == handlers
