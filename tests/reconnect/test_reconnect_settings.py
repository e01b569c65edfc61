"""reconnect=true dials what was opened and drives only the device it opened (issue 20 §1, issue 23 §1)."""

from __future__ import annotations

import time
from pathlib import Path

import pytest

import grippers
from grippers import ConnectionLost, GripperError, URLError
from grippers.errors import DeviceMismatch

from .conftest import FAST, Restartable, free_port


def wait_for(predicate, timeout: float = 15.0) -> None:  # noqa: ANN001
    deadline = time.monotonic() + timeout
    while not predicate():
        if time.monotonic() > deadline:
            raise AssertionError("condition not met in time")
        time.sleep(0.005)


def _profile_with_port(tmp_path: Path, port: int) -> Path:
    """A WSG 50 profile whose device listens on ``port``, not the protocol's default 1000."""
    path = tmp_path / "wsg50-port.toml"
    head = 'name = "wsg50-port"\nextends = "wsg50"\nurl = "wsg+tcp://127.0.0.1"\n'
    path.write_text(f"{head}\n[transport]\ntcp_port = {port}\n")
    return path


def test_reconnection_dials_the_profiles_tcp_port(tmp_path: Path, restartable) -> None:  # noqa: ANN001
    """The URL names no port; the profile's tcp_port was used at open and must be used again (it dialled
    1000, the URL parser's default, and never came back)."""
    port = free_port()
    sim: Restartable = restartable("wsg", "--listen", f"tcp://127.0.0.1:{port}", "--time-scale", "20")
    path = _profile_with_port(tmp_path, port)
    with grippers.open(path, reconnect=True, heartbeat_s=0.05, reconnect_backoff_s=0.02) as g:
        g.home()
        sim.kill()
        wait_for(lambda: not g.connected)
        sim.start()
        wait_for(lambda: g.connected)
        assert g.state().width >= 0


def test_another_model_on_the_address_is_refused(wsg_port_sim: Restartable, restartable) -> None:  # noqa: ANN001
    """A WSG 25 (20 N) coming back where a WSG 50 (80 N) was: never driven with the 50's limits."""
    port = wsg_port_sim.url.rsplit(":", 1)[1]
    with grippers.open(f"{wsg_port_sim.url}?reconnect=true&{FAST}") as g:
        assert g.info().model == "WSG 50"
        wsg_port_sim.kill()
        wait_for(lambda: not g.connected)
        other = restartable(
            "wsg", "--profile", "wsg25", "--listen", f"tcp://127.0.0.1:{port}", "--time-scale", "20"
        )
        wait_for(lambda: isinstance(g.link_watch.last_error, DeviceMismatch))
        assert not g.connected
        with pytest.raises(ConnectionLost, match="another device answers here"):
            g.grasp(0.01, force=70)
        with pytest.raises(ConnectionLost, match="device type 5"):
            g.state()
        # The opened device back on its address is taken again.
        other.kill()
        wsg_port_sim.start()
        wait_for(lambda: g.connected)
        assert g.info().model == "WSG 50"


def test_reconnect_intervals_are_bounded() -> None:
    """1e308 s overflowed the reconnection thread's condition wait; refused at open, naming the setting."""
    for name in ("reconnect_backoff_s", "reconnect_backoff_max_s", "heartbeat_s"):
        with pytest.raises(URLError, match=name):
            grippers.open(f"sim://wsg50?reconnect=true&{name}=1e308")
        with pytest.raises(GripperError, match=name):
            grippers.open("sim://wsg50", reconnect=True, **{name: 10**400})
