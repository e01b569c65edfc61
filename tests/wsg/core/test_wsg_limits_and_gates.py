"""Issue 23 §3 and issue 19 §2 on the WSG: every number goes through the one finite check, and one rule
decides which firmware has 46h and the finger commands (the client's refusal, the backend's capabilities, the
simulator's E_CMD_UNKNOWN)."""

from __future__ import annotations

from collections.abc import Callable

import pytest

import grippers
from grippers import Capability
from grippers.drivers.errors import CommandFailed, LimitError, NotSupported
from grippers.drivers.wsg.client import WsgClient
from grippers.drivers.wsg.commands import Cmd, available
from grippers.drivers.wsg.protocol import Status


@pytest.fixture
def client(wsg_sim, wsg_client_factory) -> WsgClient:
    server = wsg_sim("tcp://127.0.0.1:0")
    return wsg_client_factory(server.url, timeout=2.0)


HUGE = 10**400  # float(HUGE) raises OverflowError: the drifted copy of the check let it escape as such


@pytest.mark.parametrize(
    "call",
    [
        lambda c: c.preposition(HUGE, 50),
        lambda c: c.preposition(50, HUGE),
        lambda c: c.preposition(float("nan"), 50),
        lambda c: c.preposition(-1.0, 50),
        lambda c: c.grip(50, 0.0),
        lambda c: c.release(True, 50),
        lambda c: c.set_force_limit(HUGE),
        lambda c: c.set_acceleration(float("inf")),
        lambda c: c.set_soft_limits(HUGE, 1.0),
    ],
    ids=[
        "width-huge",
        "speed-huge",
        "width-nan",
        "width-negative",
        "speed-zero",
        "width-bool",
        "force-huge",
        "accel-inf",
        "soft-huge",
    ],
)
def test_absurd_numbers_are_limit_errors_naming_device_and_command(
    client: WsgClient, call: Callable[[WsgClient], object]
) -> None:
    with pytest.raises(LimitError) as info:
        call(client)
    assert info.value.device == client.device and info.value.command
    assert isinstance(client.width(), float)  # nothing half-sent


@pytest.mark.parametrize("firmware", ["2.2.0", "3.0.0", "4.0.1"])
def test_one_firmware_gate_for_client_backend_and_simulator(firmware: str) -> None:
    with grippers.open(f"sim://wsg50?firmware={firmware}") as g:
        c = g.driver
        for cmd, capability, read in (
            (Cmd.GET_TEMPERATURE, Capability.TEMPERATURE, lambda: c.temperature()),
            (Cmd.GET_FINGER1_DATA, Capability.FINGER_DATA, lambda: c.finger_data(1)),
        ):
            has = available(cmd, c.firmware)
            assert (capability in g.capabilities) == has
            if has:
                try:
                    read()
                except CommandFailed as exc:  # no finger attached: the device answers, it knows the command
                    assert exc.status_name != "E_CMD_UNKNOWN"
            else:
                with pytest.raises(NotSupported):
                    read()
                # The simulator agrees: sent raw, past the client's refusal (a firmware not read yet is given
                # the benefit of the doubt), the command is unknown there.
                known, c.firmware = c.firmware, None
                try:
                    assert c.request(cmd, b"", timeout=2.0).status == Status.E_CMD_UNKNOWN
                finally:
                    c.firmware = known


def test_a_move_blocked_by_a_part_raises_axis_blocked() -> None:
    """Issue 19 §2: a final E_AXIS_BLOCKED is no success: the fingers stopped short of the width asked for."""
    with grippers.open("sim://wsg50?part_width_mm=40") as g:
        g.home()
        g.move(0.08)
        with pytest.raises(CommandFailed) as info:
            g.move(0.01)
        assert info.value.status_name == "E_AXIS_BLOCKED"
        assert g.state().width == pytest.approx(0.040, abs=0.002)  # at the part, not at 10 mm
