"""Serial links (MSG UART, WSG RS-232): the simulator process is killed and restarted behind a stable path.

A pty gets a new name at every start, so the test points a symlink at it, as udev does for a USB serial
adapter that re-enumerates (/dev/serial/by-id/...): the gripper, opened on the symlink, finds the new pty.
"""

from __future__ import annotations

import os
from collections.abc import Callable
from pathlib import Path

import grippers
from grippers import ConnectionLost

from .conftest import FAST, Restartable
from .test_reconnect import wait_for


def _point(link: Path, sim: Restartable) -> None:
    assert sim.sim is not None
    target = sim.sim.url.split("://", 1)[1].split("?", 1)[0]
    tmp = link.with_suffix(".new")
    os.symlink(target, tmp)
    os.replace(tmp, link)


def _unplug(link: Path, sim: Restartable) -> None:
    """The device goes away and udev removes its stable link with it. Left pointing at the dead pty, the
    link would lead the reconnecting client to whatever process gets that pty number next (another test's
    simulator, on a busy machine)."""
    sim.kill()
    link.unlink()


def _behind_a_link(
    restartable: Callable[..., Restartable], link: Path, family: str, time_scale: str
) -> tuple[Path, Restartable]:
    """A restartable simulator on a pty that ``link`` points at (the stable path a udev rule would give)."""
    sim = restartable(family, "--listen", "pty", "--time-scale", time_scale)
    _point(link, sim)
    return link, sim


def test_msg_uart_killed_and_restarted_behind_a_stable_path(
    restartable: Callable[..., Restartable], tmp_path: Path
) -> None:
    link, sim = _behind_a_link(restartable, tmp_path / "ttyMSG", "msg", "50")
    events: list[bool] = []
    with grippers.open(
        f"stepfoc+serial://{link}?reconnect=true&{FAST}", timeout=1.0
    ) as g:  # a first answer on a loaded machine
        g.on_connection(events.append)
        g.home()
        assert g.state().referenced
        _unplug(link, sim)
        wait_for(lambda: not g.connected)
        try:
            g.move(0.05)
        except ConnectionLost:
            pass
        else:
            raise AssertionError("a move during the outage did not raise ConnectionLost")
        sim.start()
        _point(link, sim)
        wait_for(lambda: g.connected and len(events) >= 2)  # listeners are told after the flag turns
        assert events == [False, True]
        assert not g.state().referenced  # a restarted MSG has lost its calibration (docs/protocols.md §2)
        g.home()
        assert abs(g.move(0.05).width - 0.05) < 2e-3


def test_wsg_serial_killed_and_restarted_behind_a_stable_path(
    restartable: Callable[..., Restartable], tmp_path: Path
) -> None:
    link, sim = _behind_a_link(restartable, tmp_path / "ttyWSG", "wsg", "20")
    with grippers.open(
        f"wsg+serial://{link}?reconnect=true&{FAST}", timeout=1.0
    ) as g:  # a first answer on a loaded machine
        g.home()
        _unplug(link, sim)
        wait_for(lambda: not g.connected)
        sim.start()
        _point(link, sim)
        wait_for(lambda: g.connected)
        assert not g.state().fast_stopped  # FAST STOP on a drop is a TCP rule (manual 4.0.x §1.4.2)
        g.home()
        assert abs(g.move(0.03).width - 0.03) < 1e-3
