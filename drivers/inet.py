"""IPv4 or IPv6 for a host literal, and a listening TCP socket on either: one rule for every socket we make.

``socket.create_server(("::1", 0))`` without ``family=AF_INET6`` fails ("Address family for hostname not
supported"): the WSG simulator could not serve on IPv6 loopback, and the test of it always skipped (issue 43).
Hosts reach here as the URL grammar gives them: an IPv6 literal without its brackets (``::1``), an IPv4
literal or a name. A name resolves to IPv4 here, as ``socket.create_server`` would.
"""

from __future__ import annotations

import socket


def family_of(host: str | None) -> socket.AddressFamily:
    """``AF_INET6`` for an IPv6 literal (it holds a colon), else ``AF_INET``."""
    return socket.AF_INET6 if host and ":" in host else socket.AF_INET


def tcp_listener(host: str, port: int) -> socket.socket:
    """A TCP socket listening on ``host``:``port`` (0: a free port), of the host's family."""
    return socket.create_server((host, port), family=family_of(host))
