"""Taking a lock and waiting on it in a way a KeyboardInterrupt cannot break (issue 23 §3).

Python delivers Ctrl-C as an exception at the next line the main thread runs. With ``threading.Condition``
that line can be inside ``Condition.wait`` after the lock was released and before it is taken back; the
``with`` block around the wait then releases a lock it does not hold (``RuntimeError: cannot release
un-acquired lock``, seen in CI) and the connection's state is left half-changed. The two helpers here
always come back with the lock held exactly once and hand the interrupt to the caller, which puts its state
back first and then re-raises it.

The lock must be a ``threading.RLock`` held at most once by the waiting thread: ``_is_owned`` is what tells an
acquire that was interrupted before it happened from one interrupted just after.
"""

from __future__ import annotations

import threading
from typing import Any

__all__ = ["Waiters", "hold"]


def hold(lock: Any) -> BaseException | None:
    """Hold ``lock`` whatever interrupts land meanwhile; return the first one (None if none came).

    An interrupt can also land on the way into this function, before its ``try``: a caller whose lock is
    released calls it as ``try: late = hold(lock) except BaseException as exc: late = hold(lock) or exc``."""
    interrupt: BaseException | None = None
    while True:
        try:
            if not lock._is_owned():
                lock.acquire()
            return interrupt
        except BaseException as exc:  # noqa: BLE001 - handed back to the caller, which re-raises it
            if interrupt is None:
                interrupt = exc


class Waiters:
    """A condition variable over an RLock whose :meth:`wait` survives interrupts (see the module docstring).

    Each waiter sleeps on a lock of its own, released by :meth:`notify_all`; ``waiting`` tells a notifier
    whether anybody sleeps at all, so the common case (nobody) costs one attribute read.
    """

    __slots__ = ("_lock", "_sleeping")

    def __init__(self, lock: Any) -> None:
        self._lock = lock
        self._sleeping: list[Any] = []

    @property
    def waiting(self) -> bool:
        return bool(self._sleeping)

    def wait(self, timeout: float) -> BaseException | None:
        """Release the lock (held once), sleep up to ``timeout`` s or until notified, take the lock back.

        Returns with the lock held in every case, and the interrupt that landed meanwhile, if any."""
        waiter = threading.Lock()
        waiter.acquire()
        sleeping = self._sleeping
        sleeping.append(waiter)
        interrupt: BaseException | None = None
        try:
            self._lock.release()
            waiter.acquire(True, timeout if timeout > 0 else 0)
        except BaseException as exc:  # noqa: BLE001 - handed back to the caller
            interrupt = exc
        try:
            late = hold(self._lock)
        except BaseException as exc:  # noqa: BLE001 - landed on the way into hold(): take it again
            late = hold(self._lock) or exc
        try:
            if waiter in sleeping:
                sleeping.remove(waiter)
        except BaseException as exc:  # noqa: BLE001 - an interrupt here: the waiter goes on the next notify
            late = late or exc
        return interrupt or late

    def notify_all(self) -> None:
        """Wake every sleeper (lock held)."""
        sleeping = self._sleeping
        if not sleeping:
            return
        self._sleeping = []
        for waiter in sleeping:
            try:
                waiter.release()
            except RuntimeError:  # already released
                pass

    notify = notify_all  # one waiter class for all: waking one more sleeper than needed is harmless
