"""Issue 28 §5: every built-in family passes the public conformance suite (grippers.testing.conformance) on
its simulator, over its default transport and a second one. A new family is one line in TARGETS."""

from __future__ import annotations

import pytest

from grippers.testing.conformance import ConformanceSuite

TARGETS = {
    "wsg-tcp": "sim://wsg50",  # loopback TCP
    "wsg-udp": "sim://wsg50?transport=udp",
    "msg-can": "sim://msg-150",  # STEPFOC CAN on a python-can virtual bus
    "msg-pty": "sim://msg-150?transport=pty",  # the STEPFOC UART on a pseudo-terminal
    "robotiq-tcp": "sim://robotiq-2f85",  # Modbus RTU over TCP, as a UR tool forwarder serves it
    "robotiq-pty": "sim://robotiq-2f85?transport=pty",  # Modbus RTU on an RS-485 line (a pseudo-terminal)
    "schunk-http": "sim://schunk-egu-60",  # the unit's web API (HTTP) on loopback
    "schunk-rtu": "sim://schunk-egk-25?transport=pty",  # Modbus RTU on an RS-485 line (a pseudo-terminal)
}


@pytest.mark.parametrize("conformance_target", list(TARGETS.values()), ids=list(TARGETS))
class TestBuiltinFamilies(ConformanceSuite):
    pass
