"""python-can's ``virtual`` bus with a file descriptor an event loop can wait on, while one does.

Why: python-can's ``VirtualBus`` (the in-process bus of ``sim://msg-150`` and of the tests) hands frames over
in a ``queue.Queue`` and has no ``fileno()``, so an asyncio face could only learn of a reply from the driver's
reader thread, through ``call_soon_threadsafe``: one more thread hand-over per request than a threaded caller
pays, which was most of the asyncio face's margin over the threaded call on the in-process simulator (issue 43
§8; docs/performance.md, target 13). With a descriptor the event loop reads the bus itself, as it reads
SocketCAN (drivers/stepfoc/can_reader.py), and the reply reaches its task with no hand-over.

How: the same bus, channels, queue and frames as python-can's (a ``VirtualBus`` subclass on python-can's own
channel table, so other users of the channel, ours or not, see no difference), plus a Linux ``eventfd`` that
is readable whenever a frame may be waiting. It is signalled only while a reader is registered on it
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
from can.interfaces.virtual import VirtualBus

__all__ = ["WaitableVirtualBus", "waitable"]


def waitable() -> bool:
    """Whether this platform has what the bus needs (``os.eventfd``: Linux)."""
    return hasattr(os, "eventfd")


class WaitableVirtualBus(VirtualBus):
    """python-can's ``VirtualBus`` (same arguments, same channels) with a ``fileno()`` an event loop can
    wait on while :meth:`signal_reads` is on (see the module docstring).

    While it is off, the bus is python-can's own to the instruction: its queue's ``put`` and its receive are
    python-can's, not wrappers of them (a threaded program pays nothing for the descriptor it does not use);
    turning it on sets the signalling ones on the instance."""

    def __init__(self, channel: Any = None, **kwargs: Any) -> None:
        self._fd = os.eventfd(0, os.EFD_NONBLOCK | os.EFD_CLOEXEC)
        try:
            super().__init__(channel=channel, **kwargs)
        except BaseException:
            os.close(self._fd)
            raise

    def fileno(self) -> int:
        return self._fd

    def signal_reads(self, on: bool) -> None:
        """Signal the descriptor for every frame from now on (``on``), or stop. Turned on, it is signalled
        at once if frames already wait, so a reader registered just before misses none."""
        q = self.queue
        with q.mutex:  # queue.Queue.put calls _put with it held: no frame is queued meanwhile
            if self._fd < 0:  # shut down
                return
            if on:
                vars(q)["_put"] = self._put_and_signal
                vars(self)["_recv_internal"] = self._recv_signalled
                if q._qsize() > 0:  # queue.Queue's own, under its mutex
                    os.eventfd_write(self._fd, 1)
            else:
                vars(q).pop("_put", None)
                vars(self).pop("_recv_internal", None)

    def _put_and_signal(self, item: can.Message) -> None:
        """The queue's ``_put`` while signalled (called with its mutex held): queue, then signal."""
        self.queue.queue.append(item)  # what queue.Queue._put does
        os.eventfd_write(self._fd, 1)

    def _recv_signalled(self, timeout: float | None) -> tuple[can.Message | None, bool]:
        if timeout != 0:  # a thread that blocks on the queue itself (a blocked loop's own request)
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
            self.signal_reads(False)  # no frame signals the descriptor once it is closed (it may be reused)
            with self.queue.mutex:
                fd, self._fd = self._fd, -1
            if fd >= 0:
                os.close(fd)
