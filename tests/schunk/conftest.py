"""A simulated SCHUNK unit for the family's tests, started the way ``sim://`` starts it."""

from __future__ import annotations

from collections.abc import Callable, Iterator
from typing import Any

import pytest

from grippers.backends import get_backend
from grippers.profiles import load_profile
from grippers.settings import Settings


@pytest.fixture
def schunk_sim() -> Iterator[Callable[..., Any]]:
    """``schunk_sim("schunk-egu-60", time_scale="20", fieldbus="PN")``: a running simulator (closed after the
    test; a crashed simulator fails it)."""
    servers: list[Any] = []

    def start(profile: str = "schunk-egu-60", listen: str | None = None, **settings: str) -> Any:
        server = get_backend("schunk").simulator(
            load_profile(profile),
            Settings(f"sim://{profile}", {k: str(v) for k, v in settings.items()}, {}),
            listen,
        )
        servers.append(server)
        return server

    yield start
    for server in servers:
        server.close()
    assert all(s.error is None for s in servers), [s.error for s in servers]
