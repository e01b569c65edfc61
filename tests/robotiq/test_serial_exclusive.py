"""Issue 43 §5: a second process opening the same serial device succeeded, and both then timed out as each
stole the other's replies. Every family opens its port exclusively (drivers/serial_ports.py) and a second
opener is told "busy", with the holder where /proc tells."""

from __future__ import annotations

import os
import subprocess
import sys

import pytest

import grippers
from grippers.errors import ConnectionLost

TARGETS = {
    "robotiq": ("sim://robotiq-2f85?transport=pty", "robotiq-2f85"),
    "wsg": ("sim://wsg50?transport=pty", "wsg50"),
    "msg": ("sim://msg-150?transport=pty", "msg-150"),
}


@pytest.mark.parametrize("family", sorted(TARGETS))
def test_a_serial_port_in_use_is_busy_for_a_second_opener(family: str) -> None:
    sim_url, profile = TARGETS[family]
    with grippers.open(sim_url) as holder:
        url = holder.simulator.url  # FAMILY+serial:///dev/pts/N: the pty the first gripper holds
        assert "serial://" in url, url
        with pytest.raises(ConnectionLost, match=rf"busy \(held by PID {os.getpid()} "):
            grippers.open(url, profile=profile)  # a second open in this process
        code = (
            "import grippers, sys\n"
            f"try:\n    grippers.open({url!r}, profile={profile!r})\n"
            "except grippers.ConnectionLost as exc:\n    print(exc); sys.exit(3)\n"
        )
        other = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=60)
        assert other.returncode == 3, other.stdout + other.stderr
        assert "busy" in other.stdout and f"PID {os.getpid()}" in other.stdout, other.stdout
        holder.state()  # the holder still has its gripper
