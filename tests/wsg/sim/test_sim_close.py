"""A WSG simulator whose thread outlives close()'s wait keeps its descriptors until the thread ends.

The same fault as the MSG UART server's (tests/stepfoc/test_uart_sim_close.py): ``close()`` joined the
server thread and then closed the pty (or sockets) even when the thread was still running on a starved CPU,
so the next pty or socket the process opened could take the same descriptor numbers while the old thread
still read and wrote them. Now the thread that outlives the wait releases everything itself as it ends.
The thread is held by the server's lock, which it takes on every turn of its loop; the test waits until the
thread waits for it (tests/simhold.py) before close() is called.
"""

from __future__ import annotations

import pytest

from grippers.drivers.wsg.sim import WsgModel, serve
from tests.closing import fd_is_open
from tests.simhold import wait_until_at_lock


@pytest.mark.timeout(60)
def test_a_thread_that_outlives_close_keeps_its_descriptors_until_it_ends() -> None:
    server = serve(WsgModel(), "pty")
    server.close_wait_s = 0.3
    master, wake = server._master, server._wake_r.fileno()
    thread = server._thread
    assert thread is not None
    with server.lock:
        wait_until_at_lock(thread)
        server.close()  # the thread waits for the lock: close() waits for it in vain
        assert thread.is_alive()
        assert fd_is_open(master) and fd_is_open(wake)  # not given back while the old thread may use them
    thread.join(10)
    assert not thread.is_alive()
    assert not fd_is_open(master)  # released by the thread as it ended
    assert server._wake_r.fileno() == -1
    server.close()  # still idempotent


def test_close_of_an_idle_simulator_releases_at_once() -> None:
    server = serve(WsgModel(), "pty")
    master = server._master
    server.close()
    assert server._thread is not None and not server._thread.is_alive()
    assert not fd_is_open(master)
