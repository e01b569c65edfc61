"""Every example in README.md runs as printed (issue 12 §3, issue 16 "Done when").

The harness parses the README, so it follows whatever the sections say after anyone edits them:

- a ```python block followed by a plain ``` block: the code runs in a fresh interpreter and must print the
  second block;
- a plain ``` block of ``$ command`` lines: the commands run in order in one shell session shared by the whole
  README (a command ending in ``&`` keeps running in the background, as a simulator started in one section is
  used in the next); each command's output (and what background processes printed meanwhile) must match the
  lines printed under it.

Comparison is line by line after normalising what differs between runs: Unix timestamps, pseudo-terminal
numbers and runs of spaces or dashes (table columns); a line ``...`` stands for any number of lines, a line
ending in `` ...`` for any line that starts with the text before it (a machine-dependent value). Blocks
that cannot run here (``sudo``, hardware) are ```bash blocks, which are not run. The fixed ports the README
uses are taken under a lock per network namespace, so two runs of this test on one network do not collide, and
runs in namespaces of their own (scripts/isolated.sh, as CI runs its two suites side by side) do not wait.

Under load (both cores busy) a command's output, and what background processes print in answer, can come late:
each command's output is collected until it matches the README or a bound runs out, never for a fixed pause.
A failure shows every background process's state (running, or its exit status) and what it printed.
"""

from __future__ import annotations

import fcntl
import os
import queue
import re
import signal
import subprocess
import sys
import threading
import time
from collections.abc import Iterator
from dataclasses import dataclass, field
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[2]
README = ROOT / "README.md"
START_TIMEOUT = 60.0  # seconds for a background command's first lines (a Python start under load)
SETTLE_S = 0.3  # what a process prints at once after its expected lines still belongs to it
LATE_S = 10.0  # how long output that does not match yet may still be on its way (a loaded machine)


def _lock_path() -> str:
    """One lock per network namespace: the fixed ports are the namespace's, not the machine's."""
    try:
        net = os.stat("/proc/self/ns/net").st_ino
    except OSError:
        net = 0
    return f"/tmp/grippers-readme-examples-{net}.lock"


# Examples known to fail until another change lands (key: text in the example, value: why); the mark goes
# when the change has landed. Empty: every example runs as printed.
XFAIL: dict[str, str] = {}


@dataclass
class Example:
    kind: str  # "python" or "shell"
    line: int  # where it starts in README.md
    code: str = ""
    expected: list[str] = field(default_factory=list)
    commands: list[tuple[str, list[str]]] = field(default_factory=list)

    @property
    def name(self) -> str:
        first = self.code.strip().splitlines()[1 if self.kind == "python" else 0] if self.code else ""
        if self.kind == "shell":
            first = self.commands[0][0]
        return f"L{self.line}-{self.kind}-{re.sub(r'[^A-Za-z0-9]+', '-', first)[:40].strip('-')}"


def _blocks(text: str) -> list[tuple[str, int, list[str]]]:
    """(language, first line number, lines) of every fenced block."""
    out: list[tuple[str, int, list[str]]] = []
    current: list[str] | None = None
    lang, start = "", 0
    for number, line in enumerate(text.splitlines(), start=1):
        if line.startswith("```"):
            if current is None:
                current, lang, start = [], line[3:].strip(), number
            else:
                out.append((lang, start, current))
                current = None
        elif current is not None:
            current.append(line)
    return out


def parse(text: str) -> list[Example]:
    blocks = _blocks(text)
    examples: list[Example] = []
    for i, (lang, start, lines) in enumerate(blocks):
        if lang == "python" and i + 1 < len(blocks) and blocks[i + 1][0] == "":
            nxt_start = blocks[i + 1][1]
            between = text.splitlines()[start + len(lines) + 1 : nxt_start - 1]
            if not any(line.strip() for line in between):  # the output block follows at once
                examples.append(Example("python", start, "\n".join(lines), blocks[i + 1][2]))
        elif lang == "" and lines and lines[0].startswith("$ "):
            ex = Example("shell", start)
            for line in lines:
                if line.startswith("$ "):
                    ex.commands.append((line[2:], []))
                elif ex.commands:
                    ex.commands[-1][1].append(line)
            examples.append(ex)
    return examples


EXAMPLES = parse(README.read_text())

_TIME = re.compile(r"\b1[0-9]{9}\.[0-9]+")
_PTY = re.compile(r"/dev/pts/[0-9]+")


def normalise(line: str) -> str:
    line = _PTY.sub("/dev/pts/N", _TIME.sub("T", line))
    line = re.sub(r"-{2,}", "--", line)
    return " ".join(line.split())


def matches(actual: list[str], expected: list[str]) -> bool:
    """Line by line after normalising; an expected ``...`` line matches any number of actual lines."""
    act = [normalise(a) for a in actual if a.strip()]
    exp = [normalise(e) for e in expected if e.strip()]

    def same(a: str, e: str) -> bool:  # "text ..." stands for any line that starts with "text"
        return a == e or (e.endswith(" ...") and a.startswith(e[:-4]))

    def go(i: int, j: int) -> bool:
        if j == len(exp):
            return i == len(act)
        if exp[j] == "...":
            return any(go(k, j + 1) for k in range(i, len(act) + 1))
        return i < len(act) and same(act[i], exp[j]) and go(i + 1, j + 1)

    return go(0, 0)


def _pump(proc: subprocess.Popen, lines: queue.Queue[tuple[float, str]]) -> threading.Thread:
    """Each output line with the time it arrived, so lines of several processes merge as a terminal shows
    them."""

    def run() -> None:
        assert proc.stdout is not None
        for line in proc.stdout:
            lines.put((time.monotonic(), line.rstrip("\n")))

    thread = threading.Thread(target=run, daemon=True)
    thread.start()
    return thread


def _drain(lines: queue.Queue[tuple[float, str]]) -> list[tuple[float, str]]:
    out = []
    while True:
        try:
            out.append(lines.get_nowait())
        except queue.Empty:
            return out


@dataclass
class Background:
    """A command the session left running (``cmd &``), with everything it printed, for the failure report."""

    command: str
    proc: subprocess.Popen
    lines: queue.Queue[tuple[float, str]]
    printed: list[str] = field(default_factory=list)

    def take(self) -> list[tuple[float, str]]:
        got = _drain(self.lines)
        self.printed += [line for _, line in got]
        return got

    def report(self) -> str:
        status = self.proc.poll()
        state = "still running" if status is None else f"exited with status {status}"
        tail = self.printed[-15:]
        return "\n".join([f"background `{self.command}`: {state}; its last lines:", *tail])


class Session:
    """One shell session for the README: background processes live until the end of the module."""

    def __init__(self, cwd: Path) -> None:
        self.cwd = cwd
        self.env = {
            **os.environ,
            "PATH": f"{Path(sys.executable).parent}{os.pathsep}{os.environ.get('PATH', '')}",
            "PYTHONUNBUFFERED": "1",
            "COLUMNS": "200",
        }
        self.background: list[Background] = []
        self.subst: dict[str, str] = {}  # what the README shows -> what this run got (pty paths)
        self.ran: set[int] = set()  # the shell examples run in this session, by line
        self.caught_up: list[int] = []

    def _apply(self, command: str) -> str:
        for shown, real in self.subst.items():
            command = command.replace(shown, real)
        return command

    def _popen(self, command: str, **kw: object) -> subprocess.Popen:
        return subprocess.Popen(
            ["bash", "-c", command],
            cwd=self.cwd,
            env=self.env,
            stdout=subprocess.PIPE,
            stderr=subprocess.STDOUT,
            text=True,
            start_new_session=True,
            **kw,  # type: ignore[arg-type]
        )

    def start(self, command: str, expected: list[str], timeout: float = START_TIMEOUT) -> list[str]:
        proc = self._popen(f"exec {self._apply(command)}")
        job = Background(command, proc, queue.Queue())
        _pump(proc, job.lines)
        self.background.append(job)
        got: list[str] = []
        want = len([e for e in expected if e.strip()])
        end = time.monotonic() + timeout
        while len(got) < want and time.monotonic() < end:
            try:
                line = job.lines.get(timeout=0.2)[1]
            except queue.Empty:
                if proc.poll() is not None:
                    break
                continue
            job.printed.append(line)
            got.append(line)
        time.sleep(SETTLE_S)  # anything more it prints at once belongs to its start
        got += [line for _, line in job.take()]
        for shown, real in zip(expected, got, strict=False):  # learn the pty path the README shows
            for a, b in zip(_PTY.findall(shown), _PTY.findall(real), strict=False):
                self.subst[a] = b
        return got

    def run(self, command: str, expected: list[str], timeout: float = 120.0) -> list[str]:
        for job in self.background:  # what came before this command is not its output
            job.take()
        proc = self._popen(self._apply(command))
        own: queue.Queue[tuple[float, str]] = queue.Queue()
        reader = _pump(proc, own)
        try:
            proc.wait(timeout)
        finally:
            if proc.poll() is None:
                os.killpg(proc.pid, signal.SIGKILL)
                proc.wait(5)
        reader.join(5)
        merged = _drain(own)
        # What background processes print in answer (the monitor's lines) comes a moment later, later still
        # on a loaded machine: collect until the whole answer is there, within a bound.
        end = time.monotonic() + LATE_S
        while True:
            time.sleep(SETTLE_S)
            for job in self.background:
                merged += job.take()
            got = [line for _, line in sorted(merged, key=lambda item: item[0])]
            if matches(got, expected) or time.monotonic() > end:
                return got

    def execute(self, example: Example) -> list[str]:
        """Run a shell example's commands in order: all of them, so that the session's state is what the
        README says. Returns the differences from the README, one text per command that differed."""
        self.ran.add(example.line)
        differences = []
        for command, expected in example.commands:
            if command.rstrip().endswith("&"):
                got = self.start(command.rstrip()[:-1].rstrip(), expected)
            else:
                got = self.run(command, expected)
            if not matches(got, expected):
                differences.append("\n".join([f"$ {command}", "--- got:", *got, "--- README:", *expected]))
        return differences

    def catch_up(self, example: Example) -> None:
        """Run the README's earlier shell examples this session has not run (their own tests check their
        output), so that this one finds what the README says is there: the simulator an earlier section
        started. They are missing when this example runs alone (``-k``), or when the examples were spread over
        several pytest-xdist workers, each with a session of its own: ``--dist loadgroup`` keeps this module's
        group on one worker, but pytest-xdist 3.8 under pytest 9.2 does not group (pytest-dev/pytest-xdist
        #1386), and under load the README's background simulator then seemed gone (issue 43 §10)."""
        for earlier in EXAMPLES:
            if earlier.line >= example.line:
                return
            if earlier.kind == "shell" and earlier.line not in self.ran:
                self.caught_up.append(earlier.line)
                self.execute(earlier)

    def report(self) -> str:
        lines = [job.report() for job in self.background]
        if self.caught_up:
            lines.append(f"this session first ran the earlier examples at lines {self.caught_up} itself")
        return "\n\n".join(lines)

    def close(self) -> None:
        for job in self.background:
            proc = job.proc
            if proc.poll() is None:
                os.killpg(proc.pid, signal.SIGTERM)
                try:
                    proc.wait(5)
                except subprocess.TimeoutExpired:
                    os.killpg(proc.pid, signal.SIGKILL)
                    proc.wait(5)


@pytest.fixture(scope="module")
def session(tmp_path_factory: pytest.TempPathFactory) -> Iterator[Session]:
    with open(_lock_path(), "w") as lock:
        fcntl.flock(lock, fcntl.LOCK_EX)  # the README's fixed ports: one run at a time on this machine
        s = Session(tmp_path_factory.mktemp("readme"))
        try:
            yield s
        finally:
            s.close()


def _params() -> list:
    out = []
    for ex in EXAMPLES:
        text = ex.code + " ".join(c for c, _ in ex.commands)
        marks = [pytest.mark.xfail(reason=why, strict=False) for key, why in XFAIL.items() if key in text]
        out.append(pytest.param(ex, id=ex.name, marks=marks))
    return out


def test_the_readme_has_examples() -> None:
    kinds = {ex.kind for ex in EXAMPLES}
    assert kinds == {"python", "shell"} and len(EXAMPLES) >= 5


@pytest.mark.parametrize("example", _params())
def test_readme_example(example: Example, session: Session) -> None:
    if example.kind == "python":
        proc = subprocess.run(
            [sys.executable, "-c", example.code], cwd=session.cwd, capture_output=True, text=True, timeout=120
        )
        assert proc.returncode == 0, proc.stderr[-2000:]
        assert matches(proc.stdout.splitlines(), example.expected), (proc.stdout, example.expected)
        return
    session.catch_up(example)
    differences = session.execute(example)
    assert not differences, "\n\n".join([*differences, session.report()])
