"""Issue 33 §3: Ctrl-C in the first ~50 ms of any command printed a traceback and exited -2 instead of 130.

In those milliseconds the CLI loads its subcommands' modules and parses the arguments, outside the handler
that turned KeyboardInterrupt into "interrupted" and 130. Two tests: one makes the interrupt land inside
chosen imports (a finder that raises KeyboardInterrupt when asked for that module, so the place is exact),
one sends real SIGINTs at several delays after the child has imported ``grippers.cli`` (what the interpreter
does before that, its own start-up and ``import grippers``, is outside any code of ours: cli/__init__.py).
"""

from __future__ import annotations

import os
import select
import signal
import subprocess
import sys
import time
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[2]

INTERRUPT_AT_IMPORT = """
import sys

class Interrupt:
    def find_spec(self, name, path=None, target=None):
        if name == sys.argv[1]:
            raise KeyboardInterrupt
        return None

sys.meta_path.insert(0, Interrupt())
from grippers.cli import main
sys.exit(main(sys.argv[2:]))
"""

# "imported" is said from inside main()'s handler (its first call, _main, wrapped): said before main(), a
# SIGINT at 0 ms on a loaded machine landed in this script's own lines, outside any code of ours.
SAY_WHEN_IMPORTED = """
import sys
import grippers.cli

inner = grippers.cli._main

def announced(argv, command):
    sys.stderr.write("imported\\n")
    sys.stderr.flush()
    return inner(argv, command)

grippers.cli._main = announced
sys.exit(grippers.cli.main(sys.argv[1:]))
"""


def _env() -> dict[str, str]:
    return {**os.environ, "PYTHONUNBUFFERED": "1"}


@pytest.mark.parametrize(
    ("module", "said"),
    [
        ("grippers.cli.probe", "grippers: interrupted"),  # the first subcommand module the parser loads
        ("grippers.cli.ros2_cmd", "grippers: interrupted"),  # the last one
        ("difflib", "grippers monitor: interrupted"),  # parsed: "did you mean" for a mistyped option
        ("grippers.drivers.captures", "grippers monitor: interrupted"),  # inside the command
    ],
)
def test_an_interrupt_while_modules_load_is_exit_130_in_one_line(module: str, said: str) -> None:
    argv = ["monitor", "-"] if module != "difflib" else ["monitor", "-", "--formt", "raw"]
    proc = subprocess.run(
        [sys.executable, "-c", INTERRUPT_AT_IMPORT, module, *argv],
        cwd=ROOT,
        stdin=subprocess.DEVNULL,
        capture_output=True,
        text=True,
        timeout=60,
        env=_env(),
    )
    assert proc.returncode == 130, proc.stderr
    assert proc.stderr.strip() == said, proc.stderr


@pytest.mark.parametrize("delay_ms", [0, 2, 5, 10, 20, 40, 80])
def test_sigint_right_after_start_is_exit_130_without_a_traceback(delay_ms: int) -> None:
    # `monitor -` on a pipe that stays open runs until the signal, wherever the signal lands.
    proc = subprocess.Popen(
        [sys.executable, "-c", SAY_WHEN_IMPORTED, "monitor", "-"],
        cwd=ROOT,
        stdin=subprocess.PIPE,
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,
        env=_env(),
    )
    try:
        assert proc.stderr is not None
        ready, _, _ = select.select([proc.stderr], [], [], 60)
        assert ready, "the child did not start within 60 s"
        first = os.read(proc.stderr.fileno(), 64)
        assert first.startswith(b"imported"), first
        time.sleep(delay_ms / 1000)
        proc.send_signal(signal.SIGINT)
        _, err = proc.communicate(timeout=60)
    finally:
        if proc.poll() is None:
            proc.kill()
            proc.communicate(timeout=30)
    text = (first + err).decode()
    assert proc.returncode == 130, text
    assert "Traceback" not in text and text.strip().splitlines()[-1].endswith(": interrupted"), text
