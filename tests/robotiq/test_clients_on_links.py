"""The Robotiq clients (Modbus RTU and the URCap's socket) on the backend kit's links: a dropped connection
is a lost link, a reply that timed out does not spoil the next exchange."""

from __future__ import annotations

import pytest

from grippers import ConnectionLost, GripperTimeout, ProtocolError
from grippers.drivers.links import LinkHolder
from grippers.drivers.robotiq.client import RobotiqClient
from grippers.drivers.robotiq.registers import ActivationState, Command
from grippers.drivers.robotiq.sim import RobotiqModel, serve
from grippers.drivers.robotiq.urcap import UrcapClient


def test_the_rtu_client_reports_a_dropped_forwarder_as_lost() -> None:
    server = serve(RobotiqModel())
    try:
        client = RobotiqClient.tcp("127.0.0.1", int(server.port or 0), timeout=5, device="fwd")
        assert client.read_status().sta is ActivationState.RESET and client.alive
        server.faults.request_close()
        with pytest.raises(ConnectionLost) as caught:
            for _ in range(100):  # the close lands within a server tick; a read after it sees it
                client.read_status(command="state")
        assert (caught.value.device, caught.value.command) == ("fwd", "state")
        assert client.lost and not client.alive
        with pytest.raises(ConnectionLost, match="down"):
            client.write_command(Command(act=True), command="home")
        client.close()
    finally:
        server.close()
    assert server.error is None


def test_a_urcap_reply_cut_short_does_not_answer_the_next_request() -> None:
    server = serve(RobotiqModel(), "urcap://127.0.0.1:0")
    try:
        client = UrcapClient("127.0.0.1", int(server.port or 0), device="urcap", timeout=0.3)
        client.write_command(Command(act=True))
        server.faults.corrupt_replies(1)  # "ack" becomes "acj": no reply, and nothing else comes
        with pytest.raises(ProtocolError, match="no URCap reply"):
            client.write_command(Command(act=True), command="home")
        client.timeout = 5.0
        assert client.get("ACT") == 1 and client.alive  # not "acjACT 1": the garbage was dropped
        client.close()
        assert not client.alive
    finally:
        server.close()
    assert server.error is None


@pytest.mark.parametrize("listen", ["pty", "tcp://127.0.0.1:0"])
def test_a_holder_of_the_client_is_the_backend_s_reconnection(listen: str) -> None:
    """LinkHolder over RobotiqClient does what the backend's reconnection does: a serial line that never broke
    is kept once the device answers again; a dropped TCP connection is replaced by a fresh, checked one."""
    server = serve(RobotiqModel(), listen)
    try:

        def connect() -> RobotiqClient:
            if server.path is not None:
                return RobotiqClient.serial(server.path, timeout=0.3, device="dev")
            return RobotiqClient.tcp("127.0.0.1", int(server.port or 0), timeout=0.3, device="dev")

        holder = LinkHolder(connect, check=lambda c: c.read_status(command="reconnect"), reuse_alive=True)
        first = holder.link
        server.faults.silent = True
        with pytest.raises(GripperTimeout):
            holder.reconnect()
        assert holder.link is first and first.alive  # a silent device: the line itself did not break
        server.faults.silent = False
        assert holder.reconnect() is first
        if server.port is not None:
            server.faults.request_close()
            with pytest.raises(ConnectionLost):
                for _ in range(100):
                    first.read_status()
            fresh = holder.reconnect()
            assert fresh is not first and fresh.alive and not first.alive
            assert fresh.read_status().sta is ActivationState.RESET
        holder.close()
        assert not holder.alive
    finally:
        server.close()
    assert server.error is None
