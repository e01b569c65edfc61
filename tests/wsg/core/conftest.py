"""Fixtures for the WSG core tests: the manuals' example packets and simulators over real transports."""

from __future__ import annotations

import itertools
import json
import os
from collections.abc import Callable, Iterator
from pathlib import Path

import pytest

from ...closing import closed_after

# Every example packet printed in the WSG manuals (a copy of /work/shared/spec/wsg-vectors.json, so the tests
# also run where that folder is absent; test_wsg_protocol checks the copy against the file when it is there).
WSG_VECTORS: list[dict[str, str]] = [
    {"hex": "AAAAAA010000E810", "direction": "host->gripper", "id": "01h"},
    {"hex": "AAAAAA01020012346D66", "direction": "host->gripper", "id": "01h"},
    {"hex": "AAAAAA2002000000B3FD", "direction": "gripper->host", "id": "20h"},
    {"hex": "AAAAAA9002000E00FD02", "direction": "gripper->host", "id": "90h"},
    {"hex": "AAAAAA300600000000001643DCCB", "direction": "gripper->host", "id": "30h"},
    {"hex": "AAAAAA2102001A0067CB", "direction": "gripper->host", "id": "21h"},
    {"hex": "AAAAAA21020000002804", "direction": "gripper->host", "id": "21h"},
]
VECTORS_FILE = Path(os.environ.get("WSG_VECTORS", "/work/shared/spec/wsg-vectors.json"))
SEEDS = Path(os.environ.get("WSG_SEEDS", "/work/shared/seeds"))

_channels = itertools.count()


@pytest.fixture
def wsg_vectors() -> list[dict[str, str]]:
    return WSG_VECTORS


@pytest.fixture
def vectors_file() -> dict:
    if not VECTORS_FILE.exists():
        pytest.skip(f"{VECTORS_FILE} not present")
    return json.loads(VECTORS_FILE.read_text())


@pytest.fixture
def seeds_dir() -> Path:
    if not SEEDS.exists():
        pytest.skip(f"{SEEDS} not present")
    return SEEDS


@pytest.fixture
def can_channel() -> str:
    """A python-can ``virtual`` channel no other test uses."""
    return f"wsg-core-{os.getpid()}-{next(_channels)}"


@pytest.fixture
def wsg_client_factory() -> Iterator[Callable[..., object]]:
    """Open WsgClients from URLs; every client is closed at teardown."""
    from grippers.drivers.wsg.client import WsgClient

    with closed_after(WsgClient.from_url) as open_client:
        yield open_client
