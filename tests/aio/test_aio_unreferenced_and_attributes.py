"""Issue 39 §3: the asyncio gripper in a notebook. One nobody references any more is closed on garbage
collection with a ResourceWarning (it left 8 threads and the transport behind each time a cell re-ran
``g = await grippers.aio.open(...)``), and it offers what the threaded gripper does (``url``, ``profile``,
``servo_stats``, the simulator of a ``sim://`` URL ...), without awaiting."""

from __future__ import annotations

import asyncio
import gc
import inspect
import threading
import warnings

import pytest

import grippers
import grippers.aio
from grippers.aio import AsyncGripper
from tests.api.test_unreferenced_grippers_close import threads_left

# What the threaded gripper holds that the asyncio one leaves to ``.sync`` on purpose: the device primitives
# (blocking calls; a face awaits the gripper's methods instead).
LEFT_TO_SYNC = {"device"}


@pytest.mark.parametrize("url", ["sim://wsg50", "sim://msg-150"])
def test_an_unreferenced_asyncio_gripper_is_closed_with_a_resource_warning(url: str) -> None:
    gc.collect()
    before = set(threading.enumerate())

    async def main() -> str:
        g = await grippers.aio.open(url)
        await g.state()
        name = g.name
        with warnings.catch_warnings(record=True) as caught:
            warnings.simplefilter("always", ResourceWarning)
            del g
            gc.collect()
        assert any(f"unclosed asyncio gripper {name}" in str(w.message) for w in caught), caught
        return name

    asyncio.run(main())
    assert threads_left(before) == []


def _attributes(cls_or_obj: object) -> set[str]:
    names = set(vars(cls_or_obj)) if not isinstance(cls_or_obj, type) else set()
    cls = cls_or_obj if isinstance(cls_or_obj, type) else type(cls_or_obj)
    names |= {n for n in dir(cls) if isinstance(inspect.getattr_static(cls, n), property)}
    return {n for n in names if not n.startswith("_")}


def test_the_asyncio_gripper_has_the_threaded_ones_attributes() -> None:
    async def main() -> None:
        async with grippers.aio.open("sim://wsg50") as g:
            sync = g.sync
            missing = _attributes(sync) - _attributes(AsyncGripper) - LEFT_TO_SYNC
            assert not missing, f"AsyncGripper lacks {sorted(missing)}"
            assert g.url == sync.url and g.profile is sync.profile and g.timeout == sync.timeout
            assert g.simulator is sync.simulator is not None
            assert g.servo_stats is None and not g.servoing
            await g.home()
            await g.servo(0.05)
            assert await g.servo_flush()
            assert g.servoing and g.servo_stats is not None and g.servo_stats.received == 1
            await g.stop()

    asyncio.run(main())


def test_record_takes_an_asyncio_gripper(tmp_path) -> None:
    """``grippers.record(...)`` raised TypeError for an AsyncGripper."""
    path = tmp_path / "run.csv"

    async def main() -> None:
        async with grippers.aio.open("sim://wsg50") as g:
            with grippers.record(path, {"left": g}, rate_hz=50) as rec:
                await g.home()
                await asyncio.sleep(0.2)
            assert rec.states > 0

    asyncio.run(main())
    header, rows = grippers.recording.read(path)
    assert [x["name"] for x in header["grippers"]] == ["left"]
    assert any(r["gripper"] == "left" and r["kind"] == "state" for r in rows)
