"""The time bounds of native reads, kept by one timer per loop (grippers/aio.py ``_Backstops``, issue 43 §8):
each read still ends at its own bound, never before it; a read answered in time never fires; an earlier bound
added after a later one is not held back by it; nothing stays armed once no read is pending."""

from __future__ import annotations

import asyncio
from typing import Any

from grippers.aio import _backstops


async def _until(predicate: Any, bound: float = 10.0) -> None:
    loop = asyncio.get_running_loop()
    deadline = loop.time() + bound
    while not predicate():
        assert loop.time() < deadline, "not within the bound"
        await asyncio.sleep(0.005)


def test_each_read_ends_at_its_own_bound_and_only_the_pending_ones() -> None:
    async def main() -> None:
        loop = asyncio.get_running_loop()
        bounds = _backstops(loop)
        assert _backstops(loop) is bounds  # one per loop
        fired: dict[str, float] = {}
        added: dict[str, float] = {}

        def add(name: str, bound: float) -> asyncio.Future[None]:
            fut: asyncio.Future[None] = loop.create_future()
            added[name] = loop.time() + bound
            bounds.add(fut, bound, lambda: fired.setdefault(name, loop.time()))
            return fut

        late = add("late", 5.0)  # armed for it first
        add("b", 0.12)
        add("a", 0.06)  # earlier than the armed timer: re-armed
        answered = add("answered", 0.03)
        bounds.remove(answered)  # answered in time
        await _until(lambda: len(fired) == 2)
        assert set(fired) == {"a", "b"}
        for name, when in fired.items():
            assert when >= added[name] - 0.002  # never before its bound (the timer's resolution aside)
        assert fired["a"] <= fired["b"]
        bounds.remove(late)
        await asyncio.sleep(0)
        assert "late" not in fired and "answered" not in fired

    asyncio.run(main())


def test_nothing_stays_armed_once_no_read_is_pending() -> None:
    async def main() -> None:
        loop = asyncio.get_running_loop()
        bounds = _backstops(loop)
        fut: asyncio.Future[None] = loop.create_future()
        fired: list[bool] = []
        bounds.add(fut, 0.02, lambda: fired.append(True))
        await _until(lambda: bool(fired))
        await asyncio.sleep(0)
        assert bounds._timer is None and not bounds._due

    asyncio.run(main())
