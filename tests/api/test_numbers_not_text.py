"""Issue 31 §1: ``move('0.05')`` moved, although the README says a value that is not a number is a LimitError.

The one finite-number check (drivers/numbers.py) parsed text with ``float()``; every motion argument of every
family and face goes through it, so the rule is tested there and on each motion, threaded and asyncio.
"""

from __future__ import annotations

import asyncio
import math
from collections.abc import Callable, Iterator
from typing import Any

import pytest

import grippers
import grippers.aio
from grippers import LimitError, URLError
from grippers.drivers.numbers import finite
from grippers.urls import to_float

from .conftest import TIME_SCALE

NOT_NUMBERS: list[Any] = ["0.05", b"0.05", "nan", True, False, None, math.nan, math.inf, -math.inf, [0.05]]


@pytest.mark.parametrize("value", NOT_NUMBERS, ids=repr)
def test_the_one_check_refuses_what_is_not_a_finite_number(value: Any) -> None:
    with pytest.raises(LimitError, match="width"):
        finite(value, "width")


def test_text_is_a_number_only_where_values_are_text_by_nature() -> None:
    assert to_float("0.05", "timeout") == 0.05  # a URL's query
    assert finite("0.05", "x", text=True) == 0.05
    with pytest.raises(URLError, match="timeout must be a finite number"):
        to_float("nan", "timeout")


@pytest.fixture(params=["wsg50", "msg-150"])
def gripper(request: pytest.FixtureRequest) -> Iterator[grippers.Gripper]:
    with grippers.open(f"sim://{request.param}?time_scale={TIME_SCALE}") as g:
        g.home()
        yield g


CALLS: dict[str, Callable[[grippers.Gripper, Any], Any]] = {
    "move width": lambda g, v: g.move(v),
    "move speed": lambda g, v: g.move(0.05, v),
    "move timeout": lambda g, v: g.move(0.05, timeout=v),
    "grasp width": lambda g, v: g.grasp(v),
    "grasp speed": lambda g, v: g.grasp(0.04, v),
    "grasp force": lambda g, v: g.grasp(0.04, force=v),
    "release width": lambda g, v: g.release(v),
    "release speed": lambda g, v: g.release(None, v),
    "check": lambda g, v: g.check(v),
    "servo width": lambda g, v: g.servo(v),
    "stream rate": lambda g, v: g.stream(v),
}


# timeout=inf is documented as no bound of the caller's own (the motion's own bounds it): not a bad value.
CASES = [
    (call, value)
    for value in ("0.05", True, math.nan, math.inf)
    for call in CALLS
    if not (call == "move timeout" and value == math.inf)
]


@pytest.mark.parametrize(("call", "value"), CASES, ids=[f"{c}-{v!r}" for c, v in CASES])
def test_every_motion_argument_refuses_text_and_non_finite_values(
    gripper: grippers.Gripper, call: str, value: Any
) -> None:
    before = gripper.state().width
    with pytest.raises(LimitError):
        CALLS[call](gripper, value)
    assert gripper.state().width == pytest.approx(before, abs=1e-4)  # nothing moved
    assert not gripper.state().moving


def test_a_width_of_none_is_a_limit_error(gripper: grippers.Gripper) -> None:
    for call in (lambda: gripper.move(None), lambda: gripper.grasp(None)):  # type: ignore[arg-type]
        with pytest.raises(LimitError, match="width must be a number, not None"):
            call()


@pytest.mark.parametrize("profile", ["wsg50", "msg-150"])
def test_the_asyncio_face_refuses_text_too(profile: str) -> None:
    async def main() -> None:
        async with grippers.aio.open(f"sim://{profile}?time_scale={TIME_SCALE}") as g:
            for call in (g.move("0.05"), g.grasp(0.04, force="20"), g.release("0.05")):
                with pytest.raises(LimitError, match="must be a number, not '"):
                    await call

    asyncio.run(main())
