"""`grippers ros2`'s targets: checked before ROS is even loaded, so these run in the normal suite."""

from __future__ import annotations

import subprocess
import sys

import pytest


@pytest.mark.parametrize(
    ("args", "said"),
    [
        (["left=sim://wsg50", "sim://msg-150"], "a name each"),
        (["left=sim://wsg50", "left=sim://msg-150"], "given twice"),
        (["left=sim://wsg50", "right=sim://msg-150", "--joint-name", "j"], "--joint-name is for one gripper"),
        (["1left=sim://wsg50", "right=sim://msg-150"], "not a ROS name"),
    ],
    ids=["unnamed", "twice", "joint name", "bad name"],
)
def test_several_targets_need_a_valid_name_each(args: list[str], said: str) -> None:
    proc = subprocess.run(
        [sys.executable, "-m", "grippers", "ros2", *args], capture_output=True, text=True, timeout=60
    )
    assert proc.returncode == 2, proc.stderr
    assert said in proc.stderr and "Traceback" not in proc.stderr
