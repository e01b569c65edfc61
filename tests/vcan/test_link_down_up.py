"""The interface goes down and up (``ip link set vcan1 down/up``), or away and back, under an open gripper.

What python-can's socketcan bus does then is in drivers/canlink.py: a blocked receive raises ENETDOWN once,
sends raise it while the link is down, and a deleted interface needs a fresh socket. With ``reconnect=true``
the gripper comes back by itself; without it every call raises ConnectionLost naming the interface.

The simulators stand for grippers on the wire, which do not notice the host's interface going down: they keep
running through it. vcan1 only; MSG nodes 5-7, WSG ids 0x120/0x121 and 0x130/0x131.
"""

from __future__ import annotations

from collections.abc import Callable

import pytest

import grippers
from grippers import ConnectionLost
from grippers.drivers.stepfoc.sim import MsgModel, serve_can
from grippers.drivers.wsg.sim.model import WsgModel
from grippers.drivers.wsg.sim.transports import CanSimServer

from .conftest import FAST, wait_until

pytestmark = pytest.mark.vcan

# Generous: the bound is what a reconnection needs (one backoff step of at most 0.2 s and one exchange), but
# inside the User-Mode Linux guest of scripts/with-vcan every system call is slow and the machine is shared.
BACK_WITHIN_S = 15.0


def _down_and_up(g: grippers.Gripper, link: Callable[[str, str], None], iface: str) -> list[bool]:
    events: list[bool] = []
    g.on_connection(events.append)
    link(iface, "down")
    wait_until(lambda: not g.connected, BACK_WITHIN_S, "the link watch notices the interface went down")
    with pytest.raises(ConnectionLost):
        g.state()
    link(iface, "up")
    # listeners are told after the flag turns: the second event is waited for too
    back = "the gripper is back after the interface came up"
    wait_until(lambda: g.connected and len(events) >= 2, BACK_WITHIN_S, back)
    return events


def test_msg_reconnects_after_down_and_up(vcan1: str, link: Callable[[str, str], None]) -> None:
    with (
        serve_can([MsgModel(node=5)], f"can://socketcan/{vcan1}", time_scale=50.0),
        grippers.open(f"stepfoc+can://socketcan/{vcan1}?node=5&reconnect=true&{FAST}", timeout=0.3) as g,
    ):
        g.home()
        assert _down_and_up(g, link, vcan1) == [False, True]
        assert g.state().referenced  # the node kept running: its calibration is still there
        assert abs(g.move(0.02).width - 0.02) < 2e-3


def test_msg_without_reconnect_names_the_interface(vcan1: str, link: Callable[[str, str], None]) -> None:
    url = f"stepfoc+can://socketcan/{vcan1}?node=6"
    with serve_can([MsgModel(node=6)], f"can://socketcan/{vcan1}", time_scale=50.0):
        with grippers.open(url, timeout=0.3) as g:
            g.state()
            link(vcan1, "down")
            with pytest.raises(ConnectionLost) as lost:
                g.state()
            assert f"CAN interface {vcan1} is down" in str(lost.value)
            link(vcan1, "up")
        with grippers.open(url, timeout=0.3) as again:  # a new connection works once the interface is up
            assert again.state() is not None


def test_msg_reconnects_after_the_interface_is_deleted_and_added(
    vcan1: str, link: Callable[[str, str], None]
) -> None:
    """An unplugged and replugged USB adapter: the old socket can never work again, only a fresh bus can."""
    url = f"stepfoc+can://socketcan/{vcan1}?node=7&reconnect=true&{FAST}"
    with (
        serve_can([MsgModel(node=7)], f"can://socketcan/{vcan1}", time_scale=50.0) as old_sim,
        grippers.open(url, timeout=0.3) as g,
    ):
        g.home()
        events: list[bool] = []
        g.on_connection(events.append)
        link(vcan1, "delete")
        wait_until(lambda: not g.connected, BACK_WITHIN_S, "the link watch notices the interface is gone")
        with pytest.raises(ConnectionLost, match=vcan1):
            g.state()
        old_sim.close()  # its socket went with the interface too
        link(vcan1, "add")
        link(vcan1, "up")
        # the simulated gripper needs a fresh socket as well (a real one would simply be on the wire)
        with serve_can([MsgModel(node=7)], f"can://socketcan/{vcan1}", time_scale=50.0):
            back = "the gripper is back on the new interface"
            wait_until(lambda: g.connected and len(events) >= 2, BACK_WITHIN_S, back)
            assert events == [False, True]
            g.home()
            assert abs(g.move(0.02).width - 0.02) < 2e-3


def test_wsg_reconnects_after_down_and_up(vcan1: str, link: Callable[[str, str], None]) -> None:
    with (
        CanSimServer(
            WsgModel(), interface="socketcan", channel=vcan1, send_id=0x120, recv_id=0x121, time_scale=50.0
        ) as sim,
        grippers.open(f"{sim.url}&reconnect=true&{FAST}", timeout=0.5) as g,
    ):
        g.home()
        assert _down_and_up(g, link, vcan1) == [False, True]
        assert abs(g.move(0.03).width - 0.03) < 1e-3


def test_wsg_without_reconnect_names_the_interface(vcan1: str, link: Callable[[str, str], None]) -> None:
    with CanSimServer(
        WsgModel(), interface="socketcan", channel=vcan1, send_id=0x130, recv_id=0x131, time_scale=50.0
    ) as sim:
        with grippers.open(sim.url, timeout=0.5) as g:
            g.state()
            link(vcan1, "down")
            with pytest.raises(ConnectionLost) as lost:
                g.state()
            assert f"CAN interface {vcan1} is down" in str(lost.value)
            link(vcan1, "up")
        with grippers.open(sim.url, timeout=0.5) as again:  # a new connection works once the interface is up
            assert again.state() is not None
