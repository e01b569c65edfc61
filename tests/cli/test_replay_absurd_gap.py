"""Issue 43 §6: ``grippers sim --replay`` of a capture with an absurd time gap printed a thread traceback (a
timer of 1e300 s died in its thread) and served on. A gap beyond an hour is refused when the capture is read:
one line, exit 2 (drivers/replay.py ``relative``)."""

from __future__ import annotations

import subprocess
import sys
from pathlib import Path

import pytest

from grippers.drivers.replay import MAX_ANSWER_DELAY_S, Step, relative
from grippers.drivers.wsg.protocol import encode_packet

ROOT = Path(__file__).resolve().parents[2]


@pytest.mark.parametrize("gap", [MAX_ANSWER_DELAY_S * 2, 1e300, float("inf")])
def test_an_answer_after_an_absurd_gap_is_refused(gap: float) -> None:
    with pytest.raises(ValueError, match="after its request"):
        relative([Step(b"x", "x", [(1.0, None), (1.0 + gap, b"y")])])
    assert relative([Step(b"x", "x", [(1.0, None), (1.5, b"y")])])[0].answers == [(0.5, b"y")]


def test_sim_replay_of_such_a_capture_is_one_line_and_exit_2(tmp_path: Path) -> None:
    request = encode_packet(0x20).hex(" ")  # HOMING, as `grippers monitor --write` saves it
    answer = encode_packet(0x20, b"\x00\x00").hex(" ")
    capture = tmp_path / "gap.txt"
    capture.write_text(f"(1.000000) > {request}\n(1{'0' * 300}.0) < {answer}\n")
    r = subprocess.run(
        [
            sys.executable,
            "-m",
            "grippers",
            "sim",
            "wsg",
            "--replay",
            str(capture),
            "--listen",
            "tcp://127.0.0.1:0",
        ],
        cwd=ROOT,
        capture_output=True,
        text=True,
        timeout=60,
    )
    lines = [line for line in r.stderr.splitlines() if line.strip()]
    assert r.returncode == 2, r.stderr
    assert len(lines) == 1 and "after its request" in lines[0] and "Traceback" not in r.stderr, r.stderr
