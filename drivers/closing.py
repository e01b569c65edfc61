"""``with`` for every object of the library that holds a connection, a thread or a bus until ``close()``.

One definition instead of the same two methods in each such class: a subclass only says how it closes.
"""

from __future__ import annotations

from typing import Self


class Closing:
    """``with obj: ...`` closes ``obj`` as the block ends, however it ends (``close()`` is idempotent)."""

    def close(self) -> None:
        raise NotImplementedError

    def __enter__(self) -> Self:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()
