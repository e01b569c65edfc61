"""Ports for python-can's ``udp_multicast`` bus in tests.

The bus is one UDP port for every group on Linux (docs/protocols.md §2), so a test that wants a bus of its
own takes a private port, and a private port must never be python-can's default (43113): a simulator there
would answer every client opened without ``port=``, the very clients a test expects to reach nothing. A
port derived from the process id hit it once in a thousand runs.
"""

from __future__ import annotations

import random

DEFAULT_PORT = 43113  # python-can's UdpMulticastBus(port=...) default


def private_port() -> int:
    """A port for a test's own udp_multicast bus, never the default one."""
    while (port := random.randint(40000, 60000)) == DEFAULT_PORT:
        pass
    return port
