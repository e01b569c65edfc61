"""Issue 33 §3: ``grippers monitor -`` streams stdin line by line, with a bounded line length.

Before, ``sys.stdin.buffer.read()`` read all of stdin first: ``candump -L can0 | grippers monitor -`` printed
nothing until candump ended, and ``monitor /dev/zero`` grew to 7.9 GB in 8 s. The children run under a 2 GiB
address-space limit, so a regression fails here with a MemoryError instead of eating a shared machine.
"""

from __future__ import annotations

import os
import resource
import select
import subprocess
import sys
import time
from pathlib import Path

import pytest

from grippers.cli.monitor import MAX_LINE

ROOT = Path(__file__).resolve().parents[2]
LIMIT = 2 << 30  # bytes of address space for the child


def _limited() -> None:
    resource.setrlimit(resource.RLIMIT_AS, (LIMIT, LIMIT))


def _monitor(*args: str, **kwargs: object) -> subprocess.Popen[bytes]:
    return subprocess.Popen(
        [sys.executable, "-m", "grippers", "monitor", *args],
        cwd=ROOT,
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,
        preexec_fn=_limited,
        env={**os.environ, "PYTHONUNBUFFERED": "1"},
        **kwargs,  # type: ignore[arg-type]
    )


def _read_line(proc: subprocess.Popen[bytes], timeout: float) -> bytes:
    """One line of the child's stdout, waiting at most ``timeout`` seconds for it."""
    assert proc.stdout is not None
    fd, seen = proc.stdout.fileno(), b""
    deadline = time.monotonic() + timeout
    while b"\n" not in seen:
        left = deadline - time.monotonic()
        if left <= 0 or not select.select([fd], [], [], left)[0]:
            return seen
        piece = os.read(fd, 4096)
        if not piece:
            return seen
        seen += piece
    return seen


def test_each_line_of_an_open_pipe_is_decoded_as_it_comes() -> None:
    proc = _monitor("-", stdin=subprocess.PIPE)
    try:
        assert proc.stdin is not None
        proc.stdin.write(b"(1700000000.000100) vcan0 00D#0102030405060708\n")
        proc.stdin.flush()
        first = _read_line(proc, 30)
        assert b"00D" in first or b"node 0" in first, first  # decoded while the pipe is still open
        assert proc.poll() is None
        proc.stdin.write(b"(1700000000.000200) vcan0 001#\n")
        proc.stdin.flush()
        second = _read_line(proc, 30)
        assert second.strip(), second
        proc.stdin.close()
        assert proc.wait(30) == 0
    finally:
        if proc.poll() is None:
            proc.kill()
            proc.wait(30)
        for pipe in (proc.stdin, proc.stdout, proc.stderr):
            if pipe is not None:
                pipe.close()


@pytest.mark.parametrize(
    ("args", "says"),
    [
        (("/dev/zero",), b"no line end in the first"),
        (("-",), b"no line end in the first"),
        (("/dev/zero", "--format", "candump"), b"line 1 is longer than"),
        (("/dev/zero", "--format", "hex"), b"line 1 is longer than"),
    ],
    ids=["file", "stdin", "candump", "hex"],
)
def test_endless_input_without_a_line_end_is_a_quick_clear_error(args: tuple[str, ...], says: bytes) -> None:
    with open("/dev/zero", "rb") as zero:
        proc = _monitor(*args, stdin=zero)
        try:
            out, err = proc.communicate(timeout=60)
        finally:
            if proc.poll() is None:
                proc.kill()
                proc.communicate(timeout=30)
    assert proc.returncode == 2, err
    assert says in err and b"Traceback" not in err and len(err.strip().splitlines()) == 1, err


def test_an_over_long_line_later_in_a_capture_is_named(tmp_path: Path) -> None:
    capture = tmp_path / "long.log"
    good = b"(1700000000.000100) vcan0 00D#0102030405060708\n"
    capture.write_bytes(good + good + b"A" * (MAX_LINE + 10) + b"\n" + good)
    proc = _monitor(str(capture), stdin=subprocess.DEVNULL)
    out, err = proc.communicate(timeout=60)
    assert proc.returncode == 2 and b"line 3 is longer than" in err, err
    assert len(out.splitlines()) == 2  # what came before is shown


def test_raw_bytes_stream_in_bounded_pieces() -> None:
    # --format raw on an endless input: decoded piece by piece (noise records), never read whole; no packet
    # among them, so the exit code says so once -n has been reached.
    with open("/dev/zero", "rb") as zero:
        proc = _monitor("-", "--format", "raw", "-n", "3", stdin=zero)
        out, err = proc.communicate(timeout=60)
    assert proc.returncode == 1 and b"no complete packet" in err, err
    assert len(out.splitlines()) == 3 and out.count(b"skipped") == 3
