"""reconnect=true: kill and restart a simulator process on the same port; drop a connection; the settings."""

from __future__ import annotations

import asyncio
import threading
import time

import pytest

import grippers
import grippers.aio
from grippers import ConnectionLost, GripperError, URLError
from grippers.gripper import FastStopActive

from .conftest import FAST, Restartable


def wait_for(predicate, timeout: float = 10.0) -> None:  # noqa: ANN001
    deadline = time.monotonic() + timeout
    while not predicate():
        if time.monotonic() > deadline:
            raise AssertionError("condition not met in time")
        time.sleep(0.005)


def test_wsg_tcp_killed_and_restarted_on_the_same_port(wsg_port_sim: Restartable) -> None:
    events: list[bool] = []
    with grippers.open(f"{wsg_port_sim.url}?reconnect=true&{FAST}") as g:
        g.on_connection(events.append)
        g.home()
        g.move(0.03)
        stream = g.stream(100)
        assert not next(stream).gap
        wsg_port_sim.kill()
        wait_for(lambda: not g.connected)
        # During the outage every call fails at once with ConnectionLost (not a timeout after waiting).
        for call in (g.state, g.info, g.stop, lambda: g.move(0.02), lambda: g.servo(0.02)):
            with pytest.raises(ConnectionLost, match="reconnecting"):
                call()
        wsg_port_sim.start()
        wait_for(lambda: g.connected and len(events) >= 2)  # listeners are told after the flag turns
        assert events == [False, True]
        # The stream went on by itself; its first state after the outage says states were missed.
        for _ in range(200):
            st = next(stream)
            if st.gap:
                break
        else:
            raise AssertionError("no state marked as after a gap")
        stream.close()
        # A restarted (power-cycled) device: not referenced; the gripper works again after homing.
        g.home()
        assert abs(g.move(0.02).width - 0.02) < 1e-3
    assert events == [False, True, False]  # close() reports the end too


def test_calls_during_a_long_outage_never_hang(wsg_port_sim: Restartable) -> None:
    with grippers.open(f"{wsg_port_sim.url}?reconnect=true&{FAST}") as g:
        wsg_port_sim.kill()
        wait_for(lambda: not g.connected)
        watch = g.link_watch
        wait_for(lambda: watch.attempts >= 4)
        with pytest.raises(ConnectionLost):
            g.state()
        assert watch.policy.backoff_max_s == 0.1  # the backoff is bounded by the setting


def test_wsg_dropped_connection_comes_back_in_fast_stop() -> None:
    """Manual 4.0.x §1.4.2: the link dropped without 07h, so the (still powered) gripper is in FAST STOP."""
    with grippers.open(f"sim://wsg50?time_scale=20&reconnect=true&{FAST}") as g:
        g.home()
        epoch = g.link_watch.epoch
        g.simulator.faults.request_close()
        wait_for(lambda: g.link_watch.epoch > epoch and g.connected)
        assert g.state().fast_stopped
        with pytest.raises(FastStopActive):
            g.move(0.02)
        g.acknowledge()
        assert abs(g.move(0.02).width - 0.02) < 1e-3


def test_acknowledge_on_reconnect_clears_the_fast_stop() -> None:
    url = f"sim://wsg50?time_scale=20&reconnect=true&{FAST}"
    with grippers.open(url, acknowledge_on_reconnect=True) as g:
        g.home()
        epoch = g.link_watch.epoch
        g.simulator.faults.request_close()
        wait_for(lambda: g.link_watch.epoch > epoch and g.connected)
        assert not g.state().fast_stopped
        assert abs(g.move(0.02).width - 0.02) < 1e-3


def test_settings_from_keyword_url_and_default() -> None:
    with grippers.open("sim://wsg50?time_scale=20") as g:
        assert g.link_watch is None and g.connected  # off by default
        seen: list[bool] = []
        g.on_connection(seen.append)
    assert seen == [False] and not g.connected
    url = "sim://wsg50?time_scale=20&reconnect=true"
    with grippers.open(url, heartbeat_s=2, reconnect_backoff_max_s=9) as g:
        assert g.link_watch.policy.heartbeat_s == 2 and g.link_watch.policy.backoff_max_s == 9
        assert not g.link_watch.policy.acknowledge_on_reconnect  # a safety decision: off unless asked
    with pytest.raises(URLError):
        grippers.open("sim://wsg50?reconnect=maybe")
    with pytest.raises(URLError):
        grippers.open("sim://wsg50?reconnect=true&heartbeat_s=0")


def test_asyncio_stream_resumes_after_a_restart(wsg_port_sim: Restartable) -> None:
    async def main() -> None:
        async with grippers.aio.open(f"{wsg_port_sim.url}?reconnect=true&{FAST}") as g:
            ups: list[bool] = []
            g.on_connection(ups.append)
            states = []
            async for st in g.stream(100):
                states.append(st)
                if len(states) == 3:
                    await asyncio.get_running_loop().run_in_executor(None, wsg_port_sim.kill)
                    with pytest.raises(ConnectionLost):
                        while True:  # the watch notices within its poll period
                            await g.state()
                            await asyncio.sleep(0.01)
                    threading.Thread(target=wsg_port_sim.start).start()
                if st.gap:
                    break
            for _ in range(500):  # listeners are told after the flag turns: wait for the second event
                if len(ups) >= 2:
                    break
                await asyncio.sleep(0.01)
            assert ups[:2] == [False, True]
            assert sum(s.gap for s in states) == 1

    asyncio.run(asyncio.wait_for(main(), 30))


def test_a_device_without_reconnection_refuses_reconnect() -> None:
    with grippers.open("sim://wsg50?time_scale=20") as g:
        reconnection, g.device.reconnection = g.device.reconnection, None
        try:
            with pytest.raises(GripperError, match="cannot reconnect"):
                g._reconnect()
        finally:
            g.device.reconnection = reconnection


def test_wsg_udp_simulator_restarted_on_the_same_port(restartable) -> None:  # noqa: ANN001
    """UDP has no connection to lose: a device that stops answering is lost after two missed heartbeats."""
    import socket

    with socket.socket(socket.AF_INET, socket.SOCK_DGRAM) as s:
        s.bind(("127.0.0.1", 0))
        port = s.getsockname()[1]
    sim = restartable("wsg", "--listen", f"udp://127.0.0.1:{port}", "--time-scale", "20")
    with grippers.open(f"{sim.url}&reconnect=true&{FAST}", timeout=0.2) as g:
        g.home()
        sim.kill()
        wait_for(lambda: not g.connected)
        with pytest.raises(ConnectionLost):
            g.move(0.02)
        sim.start()
        wait_for(lambda: g.connected)
        g.home()
        assert abs(g.move(0.02).width - 0.02) < 1e-3


def test_a_lost_link_ends_servoing_and_servo_starts_afresh_after_it() -> None:
    with grippers.open(f"sim://wsg50?time_scale=20&reconnect=true&{FAST}") as g:
        g.home()
        g.servo(0.03)
        assert g.servo_flush(2.0)
        epoch = g.link_watch.epoch
        g.simulator.faults.request_close()
        wait_for(lambda: g.link_watch.epoch > epoch and g.connected)
        assert not g.servoing  # ended with the link: no stale target or error carried over
        with pytest.raises(FastStopActive):
            g.servo(0.04)
        g.acknowledge()
        g.servo(0.04)
        assert g.servo_flush(2.0)
        wait_for(lambda: abs(g.state().width - 0.04) < 1e-3 and not g.state().moving)


def test_a_profile_connection_table_switches_reconnection_on(tmp_path) -> None:  # noqa: ANN001
    from pathlib import Path

    source = grippers.load_profile("wsg50").path
    assert source is not None
    text = Path(source).read_text()
    text = text.replace('name = "wsg50"', 'name = "wsg50-cell"').replace('aliases = ["wsg-50", "WSG 50"]', "")
    text += "\n[connection]\nreconnect = true\nheartbeat_s = 0.25\nacknowledge_on_reconnect = true\n"
    path = tmp_path / "wsg50-cell.toml"
    path.write_text(text)
    with grippers.open(path, url="sim://?time_scale=20") as g:
        assert g.link_watch is not None
        assert g.link_watch.policy.heartbeat_s == 0.25 and g.link_watch.policy.acknowledge_on_reconnect
    with grippers.open(path, url="sim://?time_scale=20", reconnect=False) as g:
        assert g.link_watch is None  # the keyword wins over the profile
