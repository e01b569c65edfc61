"""The API scenario of tests/api over ``zenoh://``: a WSG and an MSG served by one ``grippers serve``."""

from __future__ import annotations

import time
from collections.abc import Iterator

import pytest

import grippers

from ..scenario import run_scenario
from .conftest import ServeProcess, sim

PARTS_MM = {"wsg50": 33.0, "msg-150": 31.5}  # 30 % of the stroke, as in tests/api


@pytest.fixture(scope="module")
def pair() -> Iterator[ServeProcess]:
    server = ServeProcess(
        f"wsg={sim('wsg50', part_width_mm=PARTS_MM['wsg50'])}",
        f"msg={sim('msg-150', part_width_mm=PARTS_MM['msg-150'])}",
    )
    yield server
    assert server.close() == 0  # SIGTERM: every gripper closed cleanly, exit code 0


@pytest.mark.timeout(60)
@pytest.mark.parametrize(("name", "profile"), [("wsg", "wsg50"), ("msg", "msg-150")])
def test_scenario(pair: ServeProcess, name: str, profile: str) -> None:
    with grippers.open(pair.urls[name]) as g:
        run_scenario(g, profile, PARTS_MM[profile] / 1000)


@pytest.mark.timeout(60)
def test_handles_streams_and_errors(pair: ServeProcess) -> None:
    with grippers.open(pair.urls["wsg"]) as g:
        g.home()
        # A cancelled handle: the motion stops short of its target and wait() returns or raises.
        handle = g.move(g.limits.min_width + 0.001, g.limits.min_speed, wait=False)
        time.sleep(0.05)
        assert not handle.done()
        handle.cancel()
        try:
            handle.wait(5)
        except grippers.GripperError:
            pass
        assert g.state().width > g.limits.min_width + 0.002
        # The stream is a subscription: sequence numbers without gaps, states in order.
        with g.stream(rate_hz=1000) as states:
            got = [states.get(2) for _ in range(10)]
            assert states.missed == 0 and states.out_of_order == 0
        assert [s.timestamp for s in got] == sorted(s.timestamp for s in got)
        # Optional capabilities cross too; errors keep their class.
        assert -20 < g.temperature() < 80
        g.set_device_tag("bench-1")
        assert g.device_tag() == "bench-1"
    with grippers.open(pair.urls["msg"]) as m, pytest.raises(grippers.NotSupported, match="device_tag"):
        m.device_tag()


def test_unknown_name_and_missing_endpoint(pair: ServeProcess) -> None:
    with pytest.raises(grippers.ConnectionLost, match="no answer"):
        grippers.open(f"zenoh://nobody?connect={pair.endpoint}", timeout=0.3)
    with pytest.raises(grippers.URLError, match="connect"):
        grippers.open("zenoh://wsg")
    with pytest.raises(grippers.URLError, match="unknown setting"):
        grippers.open(f"zenoh://wsg?connect={pair.endpoint}&bogus=1")
