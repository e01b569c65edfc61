"""python-can's ``virtual`` bus as the library opens it (drivers/virtual_can.py): python-can's channels and
frames, plus a descriptor that is readable whenever a frame waits, while a reader has asked for it."""

from __future__ import annotations

import os
import select
import threading
import time
import uuid
from collections.abc import Iterator

import can
import pytest

from grippers.drivers.canlink import open_bus
from grippers.drivers.virtual_can import WaitableVirtualBus, waitable

pytestmark = pytest.mark.skipif(not waitable(), reason="needs os.eventfd (Linux)")
Pair = tuple[WaitableVirtualBus, can.BusABC]


def readable(bus: can.BusABC, wait: float = 0.0) -> bool:
    return bool(select.select([bus.fileno()], [], [], wait)[0])


def frame(n: int) -> can.Message:
    return can.Message(arbitration_id=0x100, data=n.to_bytes(4, "big"), is_extended_id=False)


@pytest.fixture
def pair() -> Iterator[Pair]:
    """(ours as open_bus makes it, python-can's own) on one fresh channel."""
    channel = f"waitable-{uuid.uuid4().hex[:12]}"
    ours = open_bus(interface="virtual", channel=channel)
    theirs = can.Bus(interface="virtual", channel=channel)
    assert isinstance(ours, WaitableVirtualBus)
    yield ours, theirs
    ours.shutdown()
    theirs.shutdown()


def test_it_talks_to_pythoncans_own_virtual_bus_both_ways(pair: Pair) -> None:
    ours, theirs = pair
    theirs.send(frame(1))
    got = ours.recv(timeout=1.0)
    assert got is not None and got.data == frame(1).data
    ours.send(frame(2))
    got = theirs.recv(timeout=1.0)
    assert got is not None and got.data == frame(2).data


def test_the_descriptor_is_signalled_only_while_asked_for(pair: Pair) -> None:
    """A threaded reader blocks on the queue: no frame costs its sender a signal then."""
    ours, theirs = pair
    theirs.send(frame(1))
    assert not readable(ours)
    ours.signal_reads(True)  # a frame already waits: readable at once
    assert readable(ours)
    got = ours.recv(timeout=0)
    assert got is not None and got.data == frame(1).data
    assert not readable(ours)
    assert ours.recv(timeout=0) is None
    ours.signal_reads(False)
    theirs.send(frame(2))
    assert not readable(ours)
    assert ours.recv(timeout=1.0) is not None


def test_every_frame_is_read_by_a_loop_that_waits_on_the_descriptor(
    pair: Pair,
) -> None:
    """Frames sent from another thread while the reader waits on the descriptor and takes one frame per
    wake (as drivers/stepfoc/can_reader.py does): all of them, in order, and the descriptor idle after."""
    ours, theirs = pair
    ours.signal_reads(True)
    count = 3000
    sender = threading.Thread(target=lambda: [theirs.send(frame(n)) for n in range(count)])
    sender.start()
    got: list[int] = []
    deadline = time.monotonic() + 30
    while len(got) < count and time.monotonic() < deadline:
        if readable(ours, 0.5):
            msg = ours.recv(timeout=0)
            if msg is not None:
                got.append(int.from_bytes(msg.data, "big"))
    sender.join(5)
    assert got == list(range(count))
    assert ours.recv(timeout=0) is None and not readable(ours)


def test_shutdown_closes_the_descriptor() -> None:
    bus = open_bus(interface="virtual", channel=f"waitable-{uuid.uuid4().hex[:12]}")
    assert isinstance(bus, WaitableVirtualBus)
    fd = bus.fileno()
    os.fstat(fd)
    bus.shutdown()
    assert bus.fileno() == -1
    with pytest.raises(OSError):
        os.fstat(fd)
    bus.signal_reads(True)  # a reader that lets go late: nothing to signal, no error
