"""The asyncio face: ``async with grippers.aio.open(url) as g: await g.move(0.05)``.

Which way, and why: the awaitables bridge to the ordinary :class:`grippers.Gripper` rather than
re-implementing each protocol over asyncio streams. The backends are where units change and where the grasp
outcome, the MSG's motion detection and the WSG's pending/final matching are decided; a second,
asyncio-native client per family and transport (TCP, UDP, serial, CAN, zenoh) would duplicate all of it, and
the sans-IO cores alone do not cover it. What the bridge must not do is spend a thread per call: each
:class:`AsyncGripper` owns a small, fixed set of worker threads started at open (:data:`WORKERS`, plus one
that runs only stop, fast stop and acknowledge), and any number of concurrent awaits queue for them, so 100
concurrent calls leave the thread count where it was. Streams are plain coroutines (no thread), and
cancelling a task that awaits a motion stops the motion on the device before ``CancelledError`` propagates.
"""

from __future__ import annotations

import asyncio
import dataclasses
import math
import os
import queue
import threading
from collections.abc import AsyncIterator, Awaitable, Callable, Generator
from typing import Any, Generic, TypeVar

from .errors import ConnectionLost, GripperError, GripperTimeout
from .gripper import DeviceInfo, GraspResult, Gripper, GripperState, MotionResult

__all__ = ["AsyncGripper", "AsyncMotionHandle", "open"]

T = TypeVar("T")

# Workers for ordinary calls (a motion blocks one while it runs; state queries take the others), plus one
# that only ever runs stop, fast stop and acknowledge, so a cancel can always reach the device at once.
WORKERS = 3
STOP_GRACE = 2.0  # s beyond the gripper's timeout for a cancelled motion to report back after the stop


class _Workers:
    """A fixed pool of threads for the blocking calls of one gripper (never grows; started at once)."""

    def __init__(self, name: str, size: int = WORKERS) -> None:
        self._jobs: queue.SimpleQueue[tuple[Callable[[], Any], asyncio.Future[Any]] | None]
        self._jobs = queue.SimpleQueue()
        self._threads = [
            threading.Thread(target=self._run, name=f"grippers-aio {name} {i}", daemon=True)
            for i in range(size)
        ]
        for t in self._threads:
            t.start()

    def submit(self, fn: Callable[[], T]) -> asyncio.Future[T]:
        fut: asyncio.Future[T] = asyncio.get_running_loop().create_future()
        self._jobs.put((fn, fut))
        return fut

    def _run(self) -> None:
        while True:
            job = self._jobs.get()
            if job is None:
                return
            fn, fut = job
            loop = fut.get_loop()
            if fut.cancelled():
                continue
            try:
                result = fn()
            except BaseException as exc:  # handed to the awaiting task, whatever it is
                _deliver(loop, fut, None, exc)
            else:
                _deliver(loop, fut, result, None)

    def close(self, timeout: float = 5.0) -> None:
        for _ in self._threads:
            self._jobs.put(None)
        current = threading.current_thread()
        for t in self._threads:
            if t is not current:
                t.join(timeout)


def _deliver(
    loop: asyncio.AbstractEventLoop, fut: asyncio.Future[Any], result: Any, exc: BaseException | None
) -> None:
    def settle() -> None:
        if fut.done():
            return
        if exc is not None:
            fut.set_exception(exc)
        else:
            fut.set_result(result)

    try:
        loop.call_soon_threadsafe(settle)
    except RuntimeError:  # the loop is closed: nobody waits any more
        pass


class AsyncMotionHandle(Generic[T]):
    """A motion started with ``wait=False``: ``await`` it for the result, ``cancel()`` to stop it."""

    def __init__(self, name: str, task: asyncio.Task[T]) -> None:
        self.name = name
        self._task = task

    def __await__(self) -> Generator[Any, None, T]:
        return self._task.__await__()

    def done(self) -> bool:
        return self._task.done()

    async def wait(self, timeout: float | None = None) -> T:
        """The result; GripperTimeout if still running after ``timeout`` (the motion goes on)."""
        done, _ = await asyncio.wait({self._task}, timeout=timeout)
        if not done:
            raise GripperTimeout(f"still running after {timeout:g} s", command=self.name)
        return self._task.result()

    async def cancel(self) -> None:
        """Stop the motion on the device; returns once the device has reported back (bounded)."""
        if self._task.done():
            return
        self._task.cancel()
        await asyncio.wait({self._task})

    def add_done_callback(self, fn: Callable[[AsyncMotionHandle[T]], Any]) -> None:
        self._task.add_done_callback(lambda _t: fn(self))


class AsyncGripper:
    """Every :class:`grippers.Gripper` method, awaitable. Open one with :func:`open`; ``.sync`` is the
    gripper underneath (its limits, profile and capabilities are plain attributes, read without awaiting)."""

    def __init__(self, gripper: Gripper, workers: _Workers) -> None:
        self.sync = gripper
        self._workers = workers
        self._control = _Workers(f"{gripper.name} control", 1)
        self._closed = False

    # -- plumbing ------------------------------------------------------------------------------------------

    def _call(self, fn: Callable[[], T], *, control: bool = False) -> asyncio.Future[T]:
        if self._closed:
            raise GripperError("the gripper is closed", device=self.sync.name)
        return (self._control if control else self._workers).submit(fn)

    async def _motion(self, name: str, fn: Callable[[], T]) -> T:
        fut = self._call(fn)
        try:
            return await asyncio.shield(fut)
        except asyncio.CancelledError:
            if not fut.done():
                await self._stop_after_cancel(fut)
            raise

    async def _stop_after_cancel(self, fut: asyncio.Future[Any]) -> None:
        """Stop the device, then let the blocking motion call report (bounded) before the cancel goes on."""
        stop = self._call(self.sync.stop, control=True)
        try:
            await asyncio.wait({stop}, timeout=self.sync.timeout + STOP_GRACE)
            await asyncio.wait({fut}, timeout=self.sync.timeout + STOP_GRACE)
        finally:
            for f in (stop, fut):  # retrieve outcomes nobody will look at (no "never retrieved" noise)
                if f.done() and not f.cancelled():
                    f.exception()

    def _start(self, name: str, fn: Callable[[], T], wait: bool) -> Awaitable[T] | AsyncMotionHandle[T]:
        if wait:
            return self._motion(name, fn)
        task = asyncio.ensure_future(self._motion(name, fn))
        return AsyncMotionHandle(name, task)

    # -- the interface ------------------------------------------------------------------------------------

    @property
    def name(self) -> str:
        return self.sync.name

    @property
    def limits(self) -> Any:
        return self.sync.limits

    @property
    def capabilities(self) -> Any:
        return self.sync.capabilities

    @property
    def connected(self) -> bool:
        return self.sync.connected

    def on_connection(self, callback: Callable[[bool], Any]) -> Callable[[], None]:
        """``callback(connected)`` in this event loop's thread when the link is lost or back."""
        loop = asyncio.get_running_loop()

        def relay(up: bool) -> None:
            try:
                loop.call_soon_threadsafe(callback, up)
            except RuntimeError:
                pass

        return self.sync.on_connection(relay)

    async def home(self, timeout: float | None = None) -> None:
        await self._motion("home", lambda: self.sync.home(timeout))

    async def move(
        self, width: float, speed: float | None = None, *, wait: bool = True, timeout: float | None = None
    ) -> MotionResult | AsyncMotionHandle[MotionResult]:
        self.sync.check(width, speed, command="move")  # limits raise here, before anything is queued
        call: Callable[[], Any] = lambda: self.sync.move(width, speed, timeout=timeout)  # noqa: E731
        started = self._start("move", call, wait)
        return await started if wait else started  # type: ignore[misc]

    async def grasp(
        self,
        width: float,
        speed: float | None = None,
        force: float | None = None,
        *,
        wait: bool = True,
        timeout: float | None = None,
    ) -> GraspResult | AsyncMotionHandle[GraspResult]:
        self.sync.check(width, speed, force, command="grasp")
        call: Callable[[], Any] = lambda: self.sync.grasp(width, speed, force, timeout=timeout)  # noqa: E731
        started = self._start("grasp", call, wait)
        return await started if wait else started  # type: ignore[misc]

    async def release(
        self,
        width: float | None = None,
        speed: float | None = None,
        *,
        wait: bool = True,
        timeout: float | None = None,
    ) -> MotionResult | AsyncMotionHandle[MotionResult]:
        self.sync.check(width, speed, command="release")
        call: Callable[[], Any] = lambda: self.sync.release(width, speed, timeout=timeout)  # noqa: E731
        started = self._start("release", call, wait)
        return await started if wait else started  # type: ignore[misc]

    async def stop(self) -> None:
        await self._call(self.sync.stop, control=True)

    async def fast_stop(self) -> None:
        await self._call(self.sync.fast_stop, control=True)

    async def acknowledge(self) -> None:
        await self._call(self.sync.acknowledge, control=True)

    async def state(self) -> GripperState:
        return await self._call(self.sync.state)

    async def info(self) -> DeviceInfo:
        return await self._call(self.sync.info)

    async def temperature(self) -> float:
        return await self._call(self.sync.temperature)

    async def set_soft_limits(self, min_width: float, max_width: float) -> None:
        await self._call(lambda: self.sync.set_soft_limits(min_width, max_width))

    async def clear_soft_limits(self) -> None:
        await self._call(self.sync.clear_soft_limits)

    async def device_tag(self) -> str:
        return await self._call(self.sync.device_tag)

    async def set_device_tag(self, tag: str) -> None:
        await self._call(lambda: self.sync.set_device_tag(tag))

    async def servo(self, width: float, speed: float | None = None, force: float | None = None) -> None:
        """Returns at once (the servo loop has its own sender): no worker is needed, nothing waits."""
        self.sync.servo(width, speed, force)

    async def stream(self, rate_hz: float = 50.0) -> AsyncIterator[GripperState]:
        """States at ``rate_hz`` as an async iterator, polled from this task (no thread of its own).

        A slow consumer does not make the stream burst to catch up; a missed reading (timeout) is skipped.
        With reconnect=true, a lost link pauses the stream and the first state after it has ``gap`` set.
        """
        if not (math.isfinite(rate_hz) and rate_hz > 0):
            raise ValueError(f"rate_hz must be a positive number, not {rate_hz!r}")
        period = 1.0 / rate_hz
        loop = asyncio.get_running_loop()
        next_at = loop.time()
        gap = False
        while not self._closed:
            try:
                item: GripperState | None = await self._call(self.sync.state)
            except GripperTimeout:
                item = None
            except ConnectionLost:
                if self.sync._watch is None:
                    raise
                while not self.sync.connected:  # reconnect=true: pause, no worker held, until it is back
                    if self._closed or self.sync._closed:
                        return
                    await asyncio.sleep(min(period, 0.05))
                gap, next_at = True, loop.time()
                continue
            if item is not None:
                if gap:
                    item, gap = dataclasses.replace(item, gap=True), False
                yield item
            next_at += period
            delay = next_at - loop.time()
            if delay < 0:
                next_at, delay = loop.time(), 0.0
            await asyncio.sleep(delay)

    async def close(self) -> None:
        """Close the gripper (on a worker: it joins the gripper's own threads, bounded), then the workers."""
        if self._closed:
            return
        closing = self._workers.submit(self.sync.close)
        self._closed = True
        try:
            await asyncio.shield(closing)
        finally:
            self._workers.close()
            self._control.close()

    async def __aenter__(self) -> AsyncGripper:
        return self

    async def __aexit__(self, *exc: object) -> None:
        await self.close()

    def __repr__(self) -> str:
        return f"<AsyncGripper {self.sync.name}{' closed' if self._closed else ''}>"


class _Opening:
    """What :func:`open` returns: ``await`` it, or use it in ``async with`` (closed at the end)."""

    def __init__(self, target: str | os.PathLike[str], overrides: dict[str, Any]) -> None:
        self._target = target
        self._overrides = overrides
        self._gripper: AsyncGripper | None = None

    async def _open(self) -> AsyncGripper:
        from . import api

        workers = _Workers(os.fspath(self._target))
        opening = workers.submit(lambda: api.open(self._target, **self._overrides))
        try:
            gripper = await asyncio.shield(opening)
        except BaseException:
            if not opening.done():  # cancelled while connecting: close what the worker opens, later
                opening.add_done_callback(lambda f: f.exception() or f.result().close())
            workers.close(timeout=0)
            raise
        return AsyncGripper(gripper, workers)

    def __await__(self) -> Generator[Any, None, AsyncGripper]:
        return self._open().__await__()

    async def __aenter__(self) -> AsyncGripper:
        self._gripper = await self._open()
        return self._gripper

    async def __aexit__(self, *exc: object) -> None:
        if self._gripper is not None:
            await self._gripper.close()


def open(target: str | os.PathLike[str], **overrides: Any) -> _Opening:  # noqa: A001 - mirrors grippers.open
    """Open a gripper for asyncio: ``async with grippers.aio.open(url) as g`` or ``g = await ...open(url)``.

    Takes what :func:`grippers.open` takes (a URL, a profile name or file, keyword overrides).
    """
    return _Opening(target, overrides)
