"""The asyncio face: ``async with grippers.aio.open(url) as g: await g.move(0.05)``.

Which way, and why: the awaitables sit on the same backends and sans-IO cores as the threaded
:class:`grippers.Gripper`, never on a copy of them. ``state()``, the call a control loop makes most, is
native: the backend starts the read (``AsyncSupport.start_state``), the driver's reader completes it,
and the reply reaches the event loop through one ``call_soon_threadsafe``: no worker thread and no thread hop
on the way out (issue 20 §2; the WSG's exchange engine and the STEPFOC bus complete a callback from the reader
that already owns the transport, as python-can's notifier does for a bus without a file descriptor). Where the
transport has one (an MSG on SocketCAN, or on python-can's ``virtual`` bus as the library opens it:
drivers/virtual_can.py), the loop itself is that reader while the face is open (``read_on_loop``;
drivers/stepfoc/can_reader.py), so the reply is decoded where its task awaits it. Motions
and the other calls run the threaded gripper's own code on a small, fixed set of worker threads started at
open (:data:`WORKERS`, plus one that runs only stop, fast stop and acknowledge): a motion lasts seconds, so a
hop costs nothing there, while the backends are where units change and where the grasp outcome, the MSG's
motion detection and the WSG's pending/final matching are decided, and a second asyncio-native copy of each
would drift. Any number of concurrent awaits queue for the workers, so 100 concurrent calls leave the thread
count where it was. Streams are plain coroutines (no thread), and cancelling a task that awaits a motion stops
the motion on the device before ``CancelledError`` propagates.

Cancelling a task that awaits any other call (``wait_for(g.state(), 0.01)`` on a silent device) gives the call
up in the driver (a native read's ``cancel``; ``AsyncSupport.abandon`` on the worker thread that runs
any other call), as Ctrl-C gives up a threaded call: its wait ends at once, so the worker is free and the
command's slot with it, and the next call goes out at once instead of queueing behind the old exchange's
timeout (issue 23 §3). The abandoned exchange is treated as a timed-out one (a late reply swallowed). What
that costs the next call of the same command is the driver's business: on the WSG one LOOP barrier first over
TCP, serial and CAN, which keep replies in order, but ``stale_ttl`` over UDP, which may reorder them
(drivers/wsg/exchanges.py); on the MSG nothing (drivers/stepfoc/can_client.py, uart_client.py).

What this face may touch of the gripper: its public methods and the one declared hook,
:meth:`grippers.Gripper.async_support` (grippers/face_support.py), nothing private. Which methods it has,
with which parameters, is grippers/commands.py's table (tests/test_command_table.py checks the twins); the
ones that only run the threaded call on a worker are made by :func:`_forwarded` from the Gripper method.
"""

from __future__ import annotations

import asyncio
import dataclasses
import inspect
import logging
import math
import os
import queue
import threading
import weakref
from collections.abc import AsyncIterator, Callable, Coroutine, Generator
from typing import Any, Concatenate, Generic, ParamSpec, TypeVar

from grippers.drivers.numbers import finite

from . import commands
from .errors import CommandFailed, ConnectionLost, GripperError, GripperTimeout, LimitError
from .gripper import Capability, GraspResult, Gripper, GripperState, MotionResult, StartedRead
from .motions import MotionHandle, wait_seconds
from .profile_model import ProfileBase
from .unclosed import close_unreferenced

__all__ = ["AsyncGripper", "AsyncMotionHandle", "open"]

T = TypeVar("T")
P = ParamSpec("P")

log = logging.getLogger(__name__)

# Workers for ordinary calls (a motion blocks one while it runs; state queries take the others), plus one
# that only ever runs stop, fast stop and acknowledge, so a cancel can always reach the device at once.
WORKERS = 3
MOTION_WORKERS = 2  # a running motion and the newer one that supersedes it, while the older one winds down
# A native state read is at most this many exchanges, each bounded by the gripper's timeout (the MSG's poll,
# then frame 26 for the cause of an error), plus slack for the reader's clock: the await's own bound.
READS_PER_STATE = 2
READ_SLACK_S = 0.25
STOP_GRACE = 2.0  # s beyond the gripper's timeout for a cancelled motion to report back after the stop


class _Workers:
    """A fixed pool of threads for the blocking calls of one gripper (never grows; started at once).

    With :meth:`give_up_with`, :meth:`give_up` of a call a worker runs gives it up in the driver
    (``abandon(thread ident)``), and the worker's next call starts afresh (``resume``): both under one guard
    with the worker's start and end of a call, so a give-up never reaches a later call of that thread.
    """

    def __init__(self, name: str, size: int = WORKERS) -> None:
        self._jobs: queue.SimpleQueue[tuple[Callable[[], Any], asyncio.Future[Any] | None] | None]
        self._jobs = queue.SimpleQueue()
        self._guard = threading.Lock()
        self._running: dict[asyncio.Future[Any], int] = {}  # a call's future -> the thread running it
        self._given_up: set[asyncio.Future[Any]] = set()
        self._abandon: Callable[[int], None] | None = None
        self._resume: Callable[[int], None] = _nothing
        self._threads = [
            threading.Thread(target=self._run, name=f"grippers-aio {name} {i}", daemon=True)
            for i in range(size)
        ]
        for t in self._threads:
            t.start()

    def spawn(self, body: Callable[[], None], name: str) -> None:
        """Run ``body`` on the pool, no result wanted (a motion's backend call; its handle reports)."""
        self._jobs.put((body, None))

    def give_up_with(self, abandon: Callable[[int], None], resume: Callable[[int], None]) -> None:
        """The gripper's hooks that give up (and forget giving up) a thread's call in the driver."""
        self._abandon, self._resume = abandon, resume

    def submit(self, fn: Callable[[], T]) -> asyncio.Future[T]:
        fut: asyncio.Future[T] = asyncio.get_running_loop().create_future()
        self._jobs.put((fn, fut))
        return fut

    def give_up(self, fut: asyncio.Future[Any]) -> None:
        """The task awaiting ``fut`` was cancelled: give its call up if a worker runs it now (a call not
        started yet is skipped by the worker, as its future is cancelled)."""
        if self._abandon is None:
            return
        with self._guard:
            ident = self._running.get(fut)
            if ident is None:  # not started (the worker skips it) or already over
                return
            self._given_up.add(fut)
            try:
                self._abandon(ident)
            except Exception:  # noqa: BLE001 - the call then ends by its own timeout, as before
                log.exception("giving up a cancelled call failed")

    def _run(self) -> None:
        while True:
            job = self._jobs.get()
            if job is None:
                return
            fn, fut = job
            if fut is None:
                try:
                    fn()
                except BaseException:  # a motion body settles its handle itself; nothing may end the worker
                    log.exception("a motion's call raised past its handle")
                continue
            loop = fut.get_loop()
            with self._guard:
                if fut.cancelled():
                    continue
                self._running[fut] = threading.get_ident()
            try:
                result = fn()
            except BaseException as exc:  # handed to the awaiting task, whatever it is
                _deliver(loop, fut, None, exc)
            else:
                _deliver(loop, fut, result, None)
            finally:
                self._finished(fut)

    def _finished(self, fut: asyncio.Future[Any]) -> None:
        with self._guard:
            ident = self._running.pop(fut)
            if fut in self._given_up:
                self._given_up.discard(fut)
                try:
                    self._resume(ident)
                except Exception:  # noqa: BLE001 - nothing may end the worker
                    log.exception("resuming after a cancelled call failed")

    def close(self, timeout: float = 5.0) -> None:
        for _ in self._threads:
            self._jobs.put(None)
        current = threading.current_thread()
        for t in self._threads:
            if t is not current:
                t.join(timeout)


def _nothing(_ident: int) -> None:
    pass


def _settle(fut: asyncio.Future[Any], result: Any, exc: BaseException | None) -> None:
    if fut.done():
        return
    if exc is not None:
        fut.set_exception(exc)
    else:
        fut.set_result(result)


def _deliver(
    loop: asyncio.AbstractEventLoop, fut: asyncio.Future[Any], result: Any, exc: BaseException | None
) -> None:
    """Complete ``fut`` from any thread: directly on the loop's own (a loop that reads the transport
    itself), else through one wake of the loop."""
    if asyncio._get_running_loop() is loop:
        _settle(fut, result, exc)
        return
    try:
        loop.call_soon_threadsafe(_settle, fut, result, exc)
    except RuntimeError:  # the loop is closed: nobody waits any more
        pass


class _Backstops:
    """The time bounds of one loop's pending native reads, kept by one timer of that loop (not one each).

    Why one: a timer per call (``call_later`` and its ``cancel``, every cancelled handle left in the loop's
    heap until it is swept) cost 5-8 % of an in-process ``await g.state()`` (issue 43 §8; docs/performance.md,
    target 13), and nearly every bound is cancelled unused. Here a read costs a dict entry; the timer is armed
    for the earliest bound and, when it fires, ends the reads whose bound has passed and re-arms for the next.
    Each read still ends at its own bound (a few milliseconds late at most, as any timer of a busy loop)."""

    __slots__ = ("_loop", "_due", "_timer", "_at")

    def __init__(self, loop: asyncio.AbstractEventLoop) -> None:
        self._loop = loop
        self._due: dict[asyncio.Future[Any], tuple[float, Callable[[], None]]] = {}
        self._timer: asyncio.TimerHandle | None = None
        self._at = math.inf

    def add(self, fut: asyncio.Future[Any], bound: float, expire: Callable[[], None]) -> None:
        """Call ``expire()`` once ``bound`` seconds have passed, unless :meth:`remove` came first."""
        at = self._loop.time() + bound
        self._due[fut] = (at, expire)
        if at < self._at:
            self._arm(at)

    def remove(self, fut: asyncio.Future[Any]) -> None:
        self._due.pop(fut, None)  # the timer stays armed: when it fires it finds nothing due, and stops

    def _arm(self, at: float) -> None:
        if self._timer is not None:
            self._timer.cancel()
        self._timer, self._at = self._loop.call_at(at, self._fire), at

    def _fire(self) -> None:
        self._timer, self._at = None, math.inf
        now = self._loop.time() + _EARLY_S
        late = [(fut, expire) for fut, (at, expire) in self._due.items() if at <= now]
        for fut, expire in late:
            del self._due[fut]
            expire()
        if self._due:
            self._arm(min(at for at, _ in self._due.values()))


_EARLY_S = 0.001  # a loop may run a timer up to its clock's resolution early: still this read's bound


def _backstops(loop: asyncio.AbstractEventLoop) -> _Backstops:
    """``loop``'s :class:`_Backstops`, made on first use (kept with the loop: it ends with it)."""
    found = _BACKSTOPS.get(loop)
    if found is None:
        found = _BACKSTOPS[loop] = _Backstops(loop)
    return found


_BACKSTOPS: weakref.WeakKeyDictionary[asyncio.AbstractEventLoop, _Backstops] = weakref.WeakKeyDictionary()


async def _awaited_read(
    loop: asyncio.AbstractEventLoop,
    fut: asyncio.Future[T],
    started: StartedRead,
    device: str,
    backstop: float,
) -> T:
    """Await a read the driver completes from its reader; give it up on cancel or at its timeout.

    Where the driver keeps the time itself (``started.timeout`` None), the loop still bounds the wait at
    ``backstop`` seconds: the driver's clock runs on its reader, and a reader that stalls (a bus read by
    another event loop that ended, issue 33 §2) must not leave this await pending for ever. The bound is kept
    by the loop's one :class:`_Backstops` timer, not a timer per call (docs/performance.md, target 13).
    """

    bound = backstop if started.timeout is None else started.timeout

    def too_late() -> None:
        if not fut.done():
            text = f"no reply within {bound:g} s"
            fut.set_exception(GripperTimeout(text, device=device, command=started.command))

    bounds = _backstops(loop)
    bounds.add(fut, bound, too_late)
    try:
        return await fut
    except BaseException:
        started.cancel()  # cancelled or timed out: the exchange is abandoned, the next call goes at once
        raise
    finally:
        bounds.remove(fut)


class AsyncMotionHandle(Generic[T]):
    """A motion started with ``wait=False``: ``await`` it for the result, ``cancel()`` to stop it. It was
    registered when the call returned, so a later call supersedes it, in call order."""

    def __init__(self, owner: AsyncGripper, handle: MotionHandle[T]) -> None:
        self.name = handle.name
        self._owner = owner
        self._handle = handle
        self._cancelled = False
        loop = asyncio.get_running_loop()
        self._future: asyncio.Future[T] = loop.create_future()
        # Retrieved at once: a superseded motion nobody awaits is an expected outcome, not asyncio's
        # "exception was never retrieved" on stderr.
        self._future.add_done_callback(_retrieve)
        handle.add_done_callback(lambda h: _deliver_handle(loop, self._future, h))

    def __await__(self) -> Generator[Any, None, T]:
        return self._result().__await__()

    async def _result(self) -> T:
        try:
            return await asyncio.shield(self._future)
        except CommandFailed:
            if self._cancelled:
                raise asyncio.CancelledError from None  # as for any asyncio future that was cancelled
            raise
        except asyncio.CancelledError:
            # The task awaiting the motion was cancelled: stop the motion on the device first (bounded), then
            # let the cancellation go on, whatever the stop met (a gripper closing meanwhile included).
            if not self._future.done():
                await self._owner._stop_after_cancel(self._handle, self._future)
            raise

    def done(self) -> bool:
        return self._handle.done()

    async def wait(self, timeout: float | None = None) -> T:
        """The result; GripperTimeout if still running after ``timeout`` (the motion goes on)."""
        done, _ = await asyncio.wait({self._future}, timeout=wait_seconds(timeout, self.name))
        if not done:
            raise GripperTimeout(f"still running after {timeout:g} s", command=self.name)
        if self._cancelled and self._future.exception() is not None:
            raise asyncio.CancelledError
        return self._future.result()

    async def cancel(self) -> None:
        """Stop the motion on the device; returns once the device has reported back (bounded). Awaiting the
        handle then raises CancelledError, as for any cancelled asyncio future."""
        if not self._future.done():
            self._cancelled = True
            await self._owner._stop_after_cancel(self._handle, self._future)

    def add_done_callback(self, fn: Callable[[AsyncMotionHandle[T]], Any]) -> None:
        self._future.add_done_callback(lambda _f: fn(self))


def _close_opened(fut: asyncio.Future[Gripper]) -> None:
    if not fut.cancelled() and fut.exception() is None:
        fut.result().close()


def _retrieve(fut: asyncio.Future[Any]) -> None:
    if not fut.cancelled():
        fut.exception()


def _deliver_handle(
    loop: asyncio.AbstractEventLoop, fut: asyncio.Future[Any], handle: MotionHandle[Any]
) -> None:
    try:
        result, error = handle.wait(0), None
    except BaseException as exc:  # handed to whoever awaits
        result, error = None, exc
    _deliver(loop, fut, result, error)


def _motion_handle(started: object) -> MotionHandle[Any]:
    assert isinstance(started, MotionHandle)  # wait=False always returns one
    return started


def _forwarded(
    method: Callable[Concatenate[Gripper, P], T],
) -> Callable[Concatenate[AsyncGripper, P], Coroutine[Any, Any, T]]:
    """The awaitable twin of a Gripper method that only runs the threaded call on a worker: the same name,
    parameters and docstring, the instance's own method (a subclass's override included), and the lane
    grippers/commands.py gives it (the control worker for an ``urgent`` command)."""
    name = method.__name__
    control = commands.COMMANDS[name].urgent

    async def twin(self: AsyncGripper, /, *args: P.args, **kwargs: P.kwargs) -> T:
        bound = getattr(self.sync, name)
        result: T = await self._call(lambda: bound(*args, **kwargs), control=control)
        return result

    twin.__name__ = name
    twin.__qualname__ = f"AsyncGripper.{name}"
    twin.__doc__ = method.__doc__
    twin.__signature__ = inspect.signature(method)  # type: ignore[attr-defined]  # read by help() and tests
    return twin


def _read_through(prop: Any) -> Any:
    """The threaded gripper's property ``prop``, read on ``.sync`` (the same name and docstring)."""
    getter = prop.fget
    return property(lambda self: getter(self.sync), doc=getter.__doc__)


class AsyncGripper:
    """Every :class:`grippers.Gripper` method, awaitable. Open one with :func:`open`; ``.sync`` is the
    gripper underneath (its limits, profile and capabilities are plain attributes, read without awaiting).

    Motions are registered on the threaded gripper in the calling task, before the first ``await``: the newer
    motion wins exactly as in the threaded API (grippers/motions.py). Their blocking backend calls run on a
    fixed pool of threads, like every other call, so concurrent awaits never add a thread.
    """

    def __init__(self, gripper: Gripper, workers: _Workers, *, read_on_loop: bool = True) -> None:
        self.sync = gripper
        self._support = support = gripper.async_support()  # the declared hook (grippers/face_support.py)
        self._workers = workers
        self._control = _Workers(f"{gripper.name} control", 1)
        for pool in (workers, self._control):  # a cancelled query or stop frees its worker at once
            pool.give_up_with(support.abandon, support.resume)
        self._motion_pool = _Workers(f"{gripper.name} motion", MOTION_WORKERS)
        support.run_motions_with(self._motion_pool.spawn)
        # The loop reads the transport itself where the driver can (a CAN bus with a file descriptor): a
        # reply then reaches its task with no thread hand-over (drivers/stepfoc/can_reader.py).
        self._loop_detach: Callable[[], None] | None = None
        if read_on_loop:
            try:
                loop = asyncio.get_running_loop()
            except RuntimeError:  # built outside a loop: its calls hand over from the reader, as before
                pass
            else:
                self._loop_detach = support.read_on(loop)
        self._closed = False  # last: one whose __init__ failed has nothing for __del__ to close

    # -- plumbing ------------------------------------------------------------------------------------------

    async def _call(self, fn: Callable[[], T], *, control: bool = False) -> T:
        if self._closed:
            raise GripperError("the gripper is closed", device=self.sync.name)
        pool = self._control if control else self._workers
        fut = pool.submit(fn)
        try:
            return await fut
        except asyncio.CancelledError:
            pool.give_up(fut)  # the worker and the command's slot are free at once (module docstring)
            raise

    async def _stop_after_cancel(self, handle: MotionHandle[Any], fut: asyncio.Future[Any]) -> None:
        """Stop the device, then let the blocking motion call report (bounded); never raises but a cancel."""
        bound = self.sync.timeout + STOP_GRACE
        if self._closed:  # close() ends the motion itself (and its control worker is gone)
            await asyncio.wait({fut}, timeout=bound)
            return
        stop = self._control.submit(handle.cancel)
        stop.add_done_callback(_retrieve)  # a stop that failed (the link went) is no news to the canceller
        await asyncio.wait({stop}, timeout=bound)
        await asyncio.wait({fut}, timeout=bound)

    async def _motion(self, start: Callable[[], object], wait: bool) -> Any:
        if self._closed:
            raise GripperError("the gripper is closed", device=self.sync.name)
        handle = AsyncMotionHandle(self, _motion_handle(start()))
        return await handle if wait else handle

    # -- the interface ------------------------------------------------------------------------------------

    # What the threaded gripper holds, read here without awaiting (issue 39 §3: a notebook user reached for
    # ``g.url`` and ``g.simulator``); ``.sync.device`` alone stays on the threaded gripper (blocking calls).
    name = _read_through(Gripper.name)
    limits = _read_through(Gripper.limits)
    connected = _read_through(Gripper.connected)
    driver = _read_through(Gripper.driver)
    servo_stats = _read_through(Gripper.servo_stats)
    servoing = _read_through(Gripper.servoing)
    link_watch = _read_through(Gripper.link_watch)

    @property
    def url(self) -> str:
        """The gripper's connection URL (``sim://`` grippers: the simulator's own transport)."""
        return self.sync.url

    @property
    def profile(self) -> ProfileBase:
        """The profile in force (its mechanics, limits and defaults)."""
        return self.sync.profile

    @property
    def timeout(self) -> float:
        """Seconds each exchange with the device may take."""
        return self.sync.timeout

    @property
    def capabilities(self) -> frozenset[Capability]:
        """What the device can do beyond the common commands."""
        return self.sync.capabilities

    @property
    def simulator(self) -> Any:
        """The in-process simulator behind a ``sim://`` gripper (its model and fault hooks), else None."""
        return self.sync.simulator

    def on_connection(self, callback: Callable[[bool], Any]) -> Callable[[], None]:
        """``callback(connected)`` in this event loop's thread when the link is lost or back."""
        loop = asyncio.get_running_loop()

        def relay(up: bool) -> None:
            try:
                loop.call_soon_threadsafe(callback, up)
            except RuntimeError:
                pass

        return self.sync.on_connection(relay)

    async def home(
        self, timeout: float | None = None, *, wait: bool = True
    ) -> None | AsyncMotionHandle[None]:
        result: None | AsyncMotionHandle[None] = await self._motion(
            lambda: self.sync.home(timeout, wait=False), wait
        )
        return result

    async def move(
        self, width: float, speed: float | None = None, *, wait: bool = True, timeout: float | None = None
    ) -> MotionResult | AsyncMotionHandle[MotionResult]:
        result: MotionResult | AsyncMotionHandle[MotionResult] = await self._motion(
            lambda: self.sync.move(width, speed, wait=False, timeout=timeout), wait
        )
        return result

    async def grasp(
        self,
        width: float,
        speed: float | None = None,
        force: float | None = None,
        *,
        wait: bool = True,
        timeout: float | None = None,
    ) -> GraspResult | AsyncMotionHandle[GraspResult]:
        result: GraspResult | AsyncMotionHandle[GraspResult] = await self._motion(
            lambda: self.sync.grasp(width, speed, force, wait=False, timeout=timeout), wait
        )
        return result

    async def release(
        self,
        width: float | None = None,
        speed: float | None = None,
        *,
        wait: bool = True,
        timeout: float | None = None,
    ) -> MotionResult | AsyncMotionHandle[MotionResult]:
        result: MotionResult | AsyncMotionHandle[MotionResult] = await self._motion(
            lambda: self.sync.release(width, speed, wait=False, timeout=timeout), wait
        )
        return result

    # Stop, fast stop and acknowledge run on the control worker (``urgent`` in grippers/commands.py), never
    # behind a query; the others queue for the ordinary workers.
    stop = _forwarded(Gripper.stop)
    fast_stop = _forwarded(Gripper.fast_stop)
    acknowledge = _forwarded(Gripper.acknowledge)
    info = _forwarded(Gripper.info)
    temperature = _forwarded(Gripper.temperature)
    set_soft_limits = _forwarded(Gripper.set_soft_limits)
    clear_soft_limits = _forwarded(Gripper.clear_soft_limits)
    device_tag = _forwarded(Gripper.device_tag)
    set_device_tag = _forwarded(Gripper.set_device_tag)

    async def state(self) -> GripperState:
        if self._closed:
            raise GripperError("the gripper is closed", device=self.sync.name)
        g, support = self.sync, self._support
        loop = asyncio.get_running_loop()
        fut: asyncio.Future[GripperState] = loop.create_future()
        started = support.start_state(lambda st, exc: _deliver(loop, fut, st, exc))
        if started is None:  # this backend reads only by blocking: a worker runs it
            return await self._call(g.state)
        return support.took_state(
            await _awaited_read(loop, fut, started, g.name, READS_PER_STATE * g.timeout + READ_SLACK_S)
        )

    def check(
        self,
        width: float | None = None,
        speed: float | None = None,
        force: float | None = None,
        *,
        command: str = "check",
    ) -> tuple[float | None, float | None, float | None]:
        """:meth:`grippers.Gripper.check`: a dry run against the limits, nothing sent, so nothing to await."""
        return self.sync.check(width, speed, force, command=command)

    def require(self, capability: Capability, command: str) -> None:
        """:meth:`grippers.Gripper.require`: NotSupported unless the device has ``capability``; local."""
        self.sync.require(capability, command)

    async def servo(self, width: float, speed: float | None = None, force: float | None = None) -> None:
        """Returns at once once servoing runs (the servo loop has its own sender). The first target of a
        servoing takes over from a running motion (a stop, and the motion's call winding down): that one goes
        through a worker, so the event loop never waits on the device."""
        if not self._support.servoing:
            self.sync.check(width, speed, force, command="servo")  # limits raise here, before anything runs
            await self._call(lambda: self.sync.servo(width, speed, force))
        else:
            self.sync.servo(width, speed, force)

    async def servo_flush(self, timeout: float = 5.0) -> bool:
        """``Gripper.servo_flush`` on a worker: the event loop never waits for the servo loop's sender."""
        return await self._call(lambda: self.sync.servo_flush(timeout))

    async def stream(self, rate_hz: float = 50.0) -> AsyncIterator[GripperState]:
        """States at ``rate_hz`` as an async iterator, polled from this task (no thread of its own).

        A slow consumer does not make the stream burst to catch up; a missed reading (timeout) is skipped.
        With reconnect=true, a lost link pauses the stream and the first state after it has ``gap`` set.
        """
        rate = finite(rate_hz, "rate_hz", command="stream")
        if rate <= 0:
            raise LimitError(f"rate_hz must be a positive number, not {rate_hz!r}", command="stream")
        period = 1.0 / rate
        loop = asyncio.get_running_loop()
        next_at = loop.time()
        gap = False
        while not self._closed:
            try:
                item: GripperState | None = await self._call(self.sync.state)
            except GripperTimeout:
                item = None
            except ConnectionLost:
                if not self._support.reconnects:
                    raise
                while not self.sync.connected:  # reconnect=true: pause, no worker held, until it is back
                    if self._closed or self._support.closed:
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
        """Close the connection (on a worker: it joins the gripper's own threads, bounded), then the workers.
        It does not move the jaws (:meth:`grippers.Gripper.close`)."""
        if self._closed:
            return
        self._closed = True
        if self._loop_detach is not None:  # on the loop's thread, before the transport closes
            detach, self._loop_detach = self._loop_detach, None
            detach()
        closing = self._workers.submit(self.sync.close)
        try:
            await asyncio.shield(closing)
        finally:
            self._workers.close()
            self._control.close()
            self._motion_pool.close()

    def _close_now(self) -> None:
        """The blocking close of a gripper nobody references any more (:meth:`__del__`), off the loop."""
        self._closed = True
        self.sync.close()
        for pool in (self._workers, self._control, self._motion_pool):
            pool.close()

    def __del__(self) -> None:
        """Closed when nobody references it any more, with a ResourceWarning (grippers/unclosed.py): the
        gripper underneath and the worker threads. A loop reading the transport itself hands it back to the
        driver's reader when it stops reading (0.2 s, :func:`open`)."""
        close_unreferenced(self, "asyncio gripper", self._close_now)

    async def __aenter__(self) -> AsyncGripper:
        return self

    async def __aexit__(self, *exc: object) -> None:
        await self.close()

    def __repr__(self) -> str:
        return f"<AsyncGripper {self.sync.name}{' closed' if self._closed else ''}>"


class _Opening:
    """What :func:`open` returns: ``await`` it, or use it in ``async with`` (closed at the end)."""

    def __init__(self, target: str | os.PathLike[str], overrides: dict[str, Any], read_on_loop: bool) -> None:
        self._read_on_loop = read_on_loop
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
                opening.add_done_callback(_close_opened)
            workers.close(timeout=0)
            raise
        return AsyncGripper(gripper, workers, read_on_loop=self._read_on_loop)

    def __await__(self) -> Generator[Any, None, AsyncGripper]:
        return self._open().__await__()

    async def __aenter__(self) -> AsyncGripper:
        self._gripper = await self._open()
        return self._gripper

    async def __aexit__(self, *exc: object) -> None:
        if self._gripper is not None:
            await self._gripper.close()


def open(  # noqa: A001 - mirrors grippers.open
    target: str | os.PathLike[str], *, read_on_loop: bool = True, **overrides: Any
) -> _Opening:
    """Open a gripper for asyncio: ``async with grippers.aio.open(url) as g`` or ``g = await ...open(url)``.

    Takes what :func:`grippers.open` takes (a URL, a profile name or file, keyword overrides).
    ``read_on_loop``: where the transport allows it (an MSG on a SocketCAN, ``udp_multicast`` or ``virtual``
    bus), the event loop reads it itself while the gripper is open and the loop runs, so a reply reaches its
    task with no thread hand-over; a loop that stops reading (blocked, idle, ended) hands the bus back to the
    driver's reader thread after 0.2 s, so the other users of the bus wait at most that long
    (drivers/stepfoc/can_reader.py). False keeps the driver's reader thread.
    """
    return _Opening(target, overrides, read_on_loop)
