"""Issue 39 §4: the Robotiq pages say what the software does. The troubleshooting rows quote the library's
own messages (a slave that does not answer, another slave id, a fault and how to clear it, a busy port), and
getting-started-robotiq shows how to simulate the URCap socket with a command line the simulator takes,
without its out-of-date "known gaps"."""

from __future__ import annotations

from pathlib import Path

import pytest

import grippers
from grippers.backends import get_backend
from grippers.backends.command_hooks import commands_of
from grippers.backends.robotiq import fault_error
from grippers.drivers.robotiq.registers import ActivationState, Fault, ObjectDetection, Status
from grippers.drivers.serial_ports import open_failure

ROOT = Path(__file__).resolve().parents[2]
TROUBLE = (ROOT / "docs" / "troubleshooting.md").read_text()
START = (ROOT / "docs" / "getting-started-robotiq.md").read_text()


def test_the_fault_rows_quote_the_messages_the_library_raises() -> None:
    st = Status(
        True, False, ActivationState.COMPLETE, ObjectDetection.AT_POSITION, Fault.OVERCURRENT, 0, 0, 3, 0
    )
    err = fault_error(st, device="robotiq-2f85@URL", command="move", url="URL")
    assert err is not None and err.message in TROUBLE, err.message
    with grippers.open("sim://robotiq-2f85") as g, pytest.raises(grippers.NotReferenced) as not_active:
        g.move(0.04)
    assert str(not_active.value).replace(g.url, "URL").split(": ", 2)[2] in TROUBLE
    assert "no answer from slave 9 within 1 s" in TROUBLE  # the profile's timeout_s is 1 s
    assert grippers.load_profile("robotiq-2f85").transport.timeout_s == 1.0
    assert "slave 5 answered instead: is that the gripper's id? (?slave=5 in the URL)" in TROUBLE
    busy = open_failure("/dev/ttyUSB0", BlockingIOError(11, "Resource temporarily unavailable"))
    assert (
        busy.startswith("/dev/ttyUSB0 is busy (held by ") and "/dev/ttyUSB0 is busy (held by PID" in TROUBLE
    )


def test_getting_started_shows_the_urcap_simulator_and_no_stale_gaps() -> None:
    assert "Known gaps" not in START
    line = "grippers sim robotiq --model hand-e --listen urcap://127.0.0.1:63352 &"
    assert line in START and "serving at robotiq+urcap://127.0.0.1:63352" in START
    assert "urcap://" in commands_of(get_backend("robotiq")).sim_example  # the --help example shows it too
    profile = grippers.load_profile("robotiq-hande")
    from grippers.settings import Settings

    server = get_backend("robotiq").simulator(
        profile, Settings("sim://robotiq-hande", {}, {}), "urcap://127.0.0.1:0"
    )
    try:
        with grippers.open(server.url, profile="robotiq-hande") as g:
            g.home()
            assert abs(g.move(0.020).width - 0.020) < 1e-3
    finally:
        server.close()
    assert "--profile robotiq-hande" in START and "robotiq-2f85 assumed" in START
