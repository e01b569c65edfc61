"""The UDP transport follows the gripper's address family: an IPv6 gripper is reachable too."""

from __future__ import annotations

import socket
import threading

import pytest

from grippers.drivers.wsg.client import WsgClient
from grippers.drivers.wsg.commands import Cmd, encode_reply
from grippers.drivers.wsg.protocol import PacketParser, encode_packet


def _has_ipv6_loopback() -> bool:
    try:
        with socket.socket(socket.AF_INET6, socket.SOCK_DGRAM) as s:
            s.bind(("::1", 0))
        return True
    except OSError:
        return False


@pytest.mark.skipif(not _has_ipv6_loopback(), reason="no IPv6 loopback on this machine")
def test_width_over_udp_to_an_ipv6_address() -> None:
    server = socket.socket(socket.AF_INET6, socket.SOCK_DGRAM)
    server.bind(("::1", 0))
    server.settimeout(5)
    port = server.getsockname()[1]

    def answer_one() -> None:
        data, addr = server.recvfrom(1024)
        (packet,) = PacketParser().feed(data)
        assert packet.command == Cmd.GET_WIDTH
        server.sendto(encode_packet(Cmd.GET_WIDTH, encode_reply(Cmd.GET_WIDTH, 0, width=42.5)), addr)

    thread = threading.Thread(target=answer_one, daemon=True)
    thread.start()
    with WsgClient.udp("::1", port, local_port=0, timeout=2) as client:
        assert client.width() == pytest.approx(42.5)
    thread.join(5)
    server.close()
