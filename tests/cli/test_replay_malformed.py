"""Issue 23 §3: ``grippers sim --replay`` of any malformed capture ends with one line and exit 2.

The capture readers and script builders are fuzzed in-process (they may only return a script or raise
ValueError, which the CLI reports as a usage error); a set of hand-made bad captures runs through the real
CLI for both families.
"""

from __future__ import annotations

import subprocess
import sys
from pathlib import Path

import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from grippers.drivers.replay import Script
from grippers.drivers.stepfoc.sim.replay import stepfoc_script
from grippers.drivers.wsg.sim.replay import wsg_script

ROOT = Path(__file__).resolve().parents[2]

BAD = {
    "empty": b"",
    "binary": bytes(range(256)) * 2,
    "nul": b"\x00" * 50,
    "no direction": b"aa aa aa 01 00 00 00 00\n",
    "only replies": b"< aa aa aa 20 02 00 00 00 00 00\n",
    "not hex": b"> zz yy\n",
    "not ascii": "> \u00fc\n".encode(),
    "bad candump id": b"(1.0) can0 ZZZ#00\n",
    "frame of 50000 bytes": b"(1.0) can0 123#" + b"00" * 50000 + b"\n",
    "fd frame of 65 bytes": b"(1.0) can0 123##0" + b"00" * 65 + b"\n",
    "nan time": b"(nan) can0 123#00\n",
    "id of 20 digits": b"(1.0) can0 12345678901234567890#00\n",
}

# Lines of both formats, whole and cut, mixed with noise: what a damaged or wrong file looks like.
LINES = st.sampled_from(
    [
        "> aa aa aa 20 00 00 00 00",
        "< aa aa aa 20 02 00 00 00 00 00",
        "1.5 > aa aa aa 21 08 00 00 00 48 42 00 00 48 42",
        "(1.000000) can0 03D#",
        "(1.000000) can0 03E#0102030405",
        "(1.0) can0 03D#R",
        "(1.0) can0 1FFFFFFF#00",
        "can0  03D   [2]  01 02",
        "# comment",
        "",
    ]
)
NOISE = st.text(alphabet=st.characters(codec="utf-8"), max_size=40)
CAPTURES = st.lists(st.one_of(LINES, NOISE, LINES.map(lambda line: line[: len(line) // 2])), max_size=12)


@settings(max_examples=300, deadline=None)
@given(CAPTURES)
def test_script_builders_return_a_script_or_raise_value_error(lines: list[str]) -> None:
    blob = "\n".join(lines).encode("utf-8", errors="surrogatepass")
    for build in (wsg_script, stepfoc_script):
        try:
            assert isinstance(build(blob, "capture"), Script)
        except ValueError:
            pass  # CaptureError is one: the CLI's one-line usage error


@settings(max_examples=200, deadline=None)
@given(st.binary(max_size=300))
def test_script_builders_survive_any_bytes(blob: bytes) -> None:
    for build in (wsg_script, stepfoc_script):
        try:
            build(blob, "capture")
        except ValueError:
            pass


@pytest.mark.parametrize("name", sorted(BAD))
@pytest.mark.parametrize("family", ["wsg", "msg"])
def test_replay_of_a_malformed_capture_is_one_line_and_exit_2(tmp_path: Path, name: str, family: str) -> None:
    capture = tmp_path / "capture.log"
    capture.write_bytes(BAD[name])
    listen = "tcp://127.0.0.1:0" if family == "wsg" else "can://virtual/grippers-replay-fuzz"
    proc = subprocess.run(
        [sys.executable, "-m", "grippers", "sim", family, "--replay", str(capture), "--listen", listen],
        cwd=ROOT,
        capture_output=True,
        text=True,
        timeout=60,  # a capture that parsed would serve until killed: the timeout fails the test
    )
    lines = [line for line in proc.stderr.splitlines() if line.strip()]
    assert proc.returncode == 2, proc.stderr
    assert len(lines) == 1 and "Traceback" not in proc.stderr
    assert lines[0].startswith(f"grippers sim: error: --replay {capture}")
