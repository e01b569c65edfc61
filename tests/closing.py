"""What the project's "start it now, close it after the test" fixtures share, so that each says only what it
starts: the bookkeeping, the closing in start order, and the check that a simulator's thread survived."""

from __future__ import annotations

import contextlib
import errno
import os
from collections.abc import Callable, Iterator
from typing import Any, ParamSpec, TypeVar

P = ParamSpec("P")
T = TypeVar("T")


@contextlib.contextmanager
def closed_after(make: Callable[P, T], *, simulator: bool = False) -> Iterator[Callable[P, T]]:
    """``make`` as a fixture hands it out: everything it made is closed when the block ends.

    ``simulator``: then fail if a simulator's thread died (its ``error``): a crash in the simulator must not
    pass for a device that went silent."""
    made: list[Any] = []

    def start(*args: P.args, **kwargs: P.kwargs) -> T:
        thing = make(*args, **kwargs)
        made.append(thing)
        return thing

    yield start
    for thing in made:
        thing.close()
        if simulator:
            assert thing.error is None, f"simulator thread died: {thing.error!r}"


def fd_is_open(fd: int) -> bool:
    """Whether descriptor ``fd`` is open in this process (a simulator's pty or socket given back, or not)."""
    try:
        os.fstat(fd)
    except OSError as exc:
        assert exc.errno == errno.EBADF
        return False
    return True
