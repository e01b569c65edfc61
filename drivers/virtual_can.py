"""python-can's ``virtual`` bus with a file descriptor an event loop can wait on, while one does.

Why: python-can's ``VirtualBus`` (the in-process bus of ``sim://msg-150`` and of the tests) hands frames over
in a ``queue.Queue`` and has no ``fileno()``, so an asyncio face could only learn of a reply from the driver's
reader thread, through ``call_soon_threadsafe``: one more thread hand-over per request than a threaded caller
pays, which was most of the asyncio face's margin over the threaded call on the in-process simulator (issue 43
§8; docs/performance.md, target 13). With a descriptor the event loop reads the bus itself, as it reads
SocketCAN (drivers/stepfoc/can_reader.py), and the reply reaches its task with no hand-over.

How: the same bus, channels and frames as python-can's (a ``VirtualBus`` subclass on python-can's own channel
table, so other users of the channel, ours or not, see no difference), plus a Linux ``eventfd`` that is
readable whenever a frame may be waiting. It is signalled only while a reader is registered on it
(:meth:`WaitableVirtualBus.signal_reads`, set by the bus reader when an event loop takes the bus and cleared
when it gives the bus back): a signal is a system call on the sender's thread, which a threaded program, whose
reader thread blocks on the queue itself, should not pay for every frame.

The rule that keeps a frame from being missed: while signalled, every frame put on the queue writes the
eventfd after it is queued (under the queue's lock), and a non-blocking receive clears the eventfd before it
takes a frame and sets it again when frames remain. So whenever the queue holds a frame the descriptor is
readable; a wake that finds the queue empty (a frame another receive took) reads nothing.
"""

from __future__ import annotations

import os
import queue
from typing import Any

import can
from can.interfaces.virtual import VirtualBus, channels_lock

__all__ = ["WaitableVirtualBus", "waitable"]


def waitable() -> bool:
    """Whether this platform has what the bus needs (``os.eventfd``: Linux)."""
    return hasattr(os, "eventfd")


class _SignallingQueue(queue.Queue[can.Message]):
    """A bus's receive queue that writes its eventfd after each frame it queues, while ``signalled``."""

    def __init__(self, fd: int, maxsize: int) -> None:
        super().__init__(maxsize)
        self.fd = fd
        self.signalled = False

    def _put(self, item: can.Message) -> None:  # called with self.mutex held (queue.Queue.put)
        super()._put(item)
        if self.signalled:
            os.eventfd_write(self.fd, 1)


class WaitableVirtualBus(VirtualBus):
    """python-can's ``VirtualBus`` (same arguments, same channels) with a ``fileno()`` an event loop can
    wait on while :meth:`signal_reads` is on (see the module docstring)."""

    def __init__(self, channel: Any = None, **kwargs: Any) -> None:
        self._fd = os.eventfd(0, os.EFD_NONBLOCK | os.EFD_CLOEXEC)
        try:
            super().__init__(channel=channel, **kwargs)
        except BaseException:
            os.close(self._fd)
            raise
        signalling = _SignallingQueue(self._fd, self.queue.maxsize)
        with channels_lock:  # swapped before anyone can have put a frame on the queue python-can made
            self.channel[self.channel.index(self.queue)] = signalling
            self.queue = signalling

    def fileno(self) -> int:
        return self._fd

    def signal_reads(self, on: bool) -> None:
        """Signal the descriptor for every frame from now on (``on``), or stop. Turned on, it is signalled
        at once if frames already wait, so a reader registered just before misses none."""
        q = self.queue
        assert isinstance(q, _SignallingQueue)
        with q.mutex:
            if self._fd < 0:  # shut down
                return
            q.signalled = on
            if on and q._qsize() > 0:
                os.eventfd_write(self._fd, 1)

    def _recv_internal(self, timeout: float | None) -> tuple[can.Message | None, bool]:
        if timeout != 0:  # a thread that blocks on the queue itself
            return super()._recv_internal(timeout)
        self._check_if_open()
        q = self.queue
        try:
            os.eventfd_read(self._fd)  # cleared first: a frame queued from here on signals again
        except BlockingIOError:
            pass
        try:
            msg = q.get_nowait()
        except queue.Empty:
            return None, False
        if not q.empty():
            os.eventfd_write(self._fd, 1)  # more wait: the descriptor stays readable for them
        return msg, False

    def shutdown(self) -> None:
        try:
            super().shutdown()
        finally:
            q = self.queue
            with q.mutex:  # no frame signals the descriptor once it is closed (it may be reused)
                if isinstance(q, _SignallingQueue):
                    q.signalled = False
                fd, self._fd = self._fd, -1
            if fd >= 0:
                os.close(fd)
