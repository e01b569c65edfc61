"""A device on a loopback TCP port answering each request with what a test's function says: for replies the
simulators never send (a value out of range, another slave id, a header that is not the protocol's)."""

from __future__ import annotations

import contextlib
import socket
import threading
from collections.abc import Callable, Iterator


@contextlib.contextmanager
def scripted_peer(answer: Callable[[bytes], bytes]) -> Iterator[int]:
    """The port of a peer that answers each request (what one read gave) with ``answer(request)``."""
    srv = socket.create_server(("127.0.0.1", 0))

    def run() -> None:
        with contextlib.suppress(OSError):
            conn, _ = srv.accept()
            with conn:
                while data := conn.recv(1024):
                    conn.sendall(answer(data))

    thread = threading.Thread(target=run, daemon=True)
    thread.start()
    try:
        yield srv.getsockname()[1]
    finally:
        srv.close()
        thread.join(5)
