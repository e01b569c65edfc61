"""A simulator whose thread outlives close()'s wait never gives its descriptors back while the thread runs.

A busy CI run (N7) failed two conformance checks on the MSG over a pty: one home saw the driver "leave
calibration mode", one open got no answer. Both fit one cause: ``close()`` joined the simulator's thread for
2 s and closed the pty even when the thread was still running (a starved CPU), so the next pty the process
opened could take the same descriptor numbers while the old thread still read and wrote them: a new client
answered by an old model. Now the thread that outlives the wait closes its descriptors itself as it ends.
The thread is held here by the model's lock, which it takes on every tick; the test waits until the thread
waits for it (tests/simhold.py) before close() is called.
"""

from __future__ import annotations

import pytest

from grippers.drivers.stepfoc.sim import MsgModel
from grippers.drivers.stepfoc.sim.uart_server import serve_uart
from tests.closing import fd_is_open
from tests.simhold import wait_until_at_lock


@pytest.mark.timeout(60)
def test_a_thread_that_outlives_close_keeps_its_descriptors_until_it_ends() -> None:
    server = serve_uart(MsgModel())
    master, thread = server._master, server._thread
    with server.lock:
        wait_until_at_lock(thread)  # the thread waits for the lock: close() waits 2 s for it in vain
        server.close()
        assert thread.is_alive()
        assert fd_is_open(master)  # not given back while the old thread may still use the number
    thread.join(10)
    assert not thread.is_alive()
    assert not fd_is_open(master)  # closed by the thread as it ended


def test_close_of_an_idle_simulator_closes_at_once() -> None:
    server = serve_uart(MsgModel())
    master = server._master
    server.close()
    assert not server._thread.is_alive() and not fd_is_open(master)
