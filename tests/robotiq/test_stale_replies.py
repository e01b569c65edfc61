"""Issue 43 §5: a late reply or a burst of garbage costs the exchange it hit, never every later one, over
Modbus RTU and over the URCap socket (whose replies carry no request id), with or without reconnection."""

from __future__ import annotations

import logging
import time

import pytest

import grippers
from grippers.drivers.robotiq import modbus
from grippers.drivers.robotiq.client import RobotiqClient
from grippers.drivers.robotiq.urcap import UrcapClient
from grippers.errors import GripperError, GripperTimeout, ProtocolError
from tests.scripted_peer import scripted_peer

TRANSPORTS = ["tcp", "pty", "urcap"]


def _settle_late(g: grippers.Gripper) -> None:
    """Until the simulator sent the delayed reply (its kit's queue of them is empty), and a moment for the
    bytes to arrive: the late reply is in before the next request goes out, however loaded the machine."""
    deadline = time.monotonic() + 10.0
    while g.simulator._delayed:  # type: ignore[attr-defined]  # the kit's server: no public view of the queue
        assert time.monotonic() < deadline, "the delayed reply was never sent"
        time.sleep(0.01)
    time.sleep(0.2)


@pytest.mark.parametrize("transport", TRANSPORTS)
@pytest.mark.parametrize("reconnect", ["false", "true"])
def test_after_one_late_reply_every_state_is_the_current_one(transport: str, reconnect: str) -> None:
    url = f"sim://robotiq-2f85?transport={transport}&activated=true&timeout=0.3&reconnect={reconnect}"
    with grippers.open(url) as g:
        g.move(0.080)
        g.simulator.faults.delay_replies(0.6)  # twice the client's timeout
        with pytest.raises(GripperError):
            g.state()
        _settle_late(g)
        g.simulator.pause()  # the jaws stand still from here: every reading can be checked exactly
        with g.simulator.lock:
            model = g.simulator.model
            model.position = model.target = 140.0  # as if the jaws had been moved (to about 34 mm)
        want = model.width_mm() / 1000
        for _ in range(3):
            assert abs(g.state().width - want) < 1e-4  # not the 80 mm of the reply that came late


@pytest.mark.parametrize("reconnect", ["false", "true"])
def test_a_garbage_burst_on_the_urcap_socket_costs_one_exchange_at_most(reconnect: str) -> None:
    url = f"sim://robotiq-2f85?transport=urcap&activated=true&timeout=0.3&reconnect={reconnect}"
    with grippers.open(url) as g:
        g.move(0.040)
        g.simulator.faults.send_garbage(bytes(range(256)) * 400)  # 100 kB before the next reply
        try:
            g.state()
        except ProtocolError as exc:  # a clear error when no reply followed in time
            assert "no URCap reply" in str(exc)
        for _ in range(3):
            assert abs(g.state().width - 0.040) < 1e-3
        assert g.driver.alive


@pytest.mark.parametrize("line", ["POS 99999", "FLT 300", "PRE 4096", "OBJ 4"])
def test_an_out_of_range_urcap_value_is_a_protocol_error(line: str) -> None:
    name = line.split()[0]

    def answer(request: bytes) -> bytes:
        asked = request.split()[1].decode()
        return (line if asked == name else f"{asked} 1").encode() + b"\n"

    with scripted_peer(answer) as port:
        client = UrcapClient("127.0.0.1", port, device="urcap-test", timeout=1.0)
        try:
            with pytest.raises(ProtocolError, match=f"{line} is out of range"):
                client.get(name)
            assert client.get("GTO") == 1  # the stream stays in step
        finally:
            client.close()


def test_a_reply_from_another_slave_id_says_so() -> None:
    def answer(request: bytes) -> bytes:  # a device given slave id 5 answers a read addressed to 9
        return modbus.read_response(5, modbus.READ_HOLDING, (0, 0, 0))

    with scripted_peer(answer) as port:
        client = RobotiqClient.tcp("127.0.0.1", port, device="rtu-test", timeout=0.3)
        try:
            with pytest.raises(GripperTimeout, match=r"no answer from slave 9.*slave 5 answered.*\?slave=5"):
                client.read_status()
        finally:
            client.close()


def test_late_replies_are_logged_not_silent(caplog: pytest.LogCaptureFixture) -> None:
    with grippers.open("sim://robotiq-2f85?transport=urcap&activated=true&timeout=0.3") as g:
        g.simulator.faults.delay_replies(0.6)
        with pytest.raises(GripperError):
            g.state()
        _settle_late(g)
        with caplog.at_level(logging.DEBUG, logger="grippers.drivers"):
            g.state()
        # Dropped as late once the next request is out, or as unasked when it came with the answer: either way
        # the log says so (which one depends on when the reply landed, not on the client).
        said = [r.getMessage() for r in caplog.records]
        assert any("late URCap reply" in m or "unasked URCap replies" in m for m in said), said
