"""Simulators in their own processes, killed and restarted on the same port (or bus) by the tests."""

from __future__ import annotations

import socket
from collections.abc import Callable, Iterator

import pytest

from ..closing import closed_after
from ..conftest import SimProcess

FAST = "heartbeat_s=0.05&reconnect_backoff_s=0.02&reconnect_backoff_max_s=0.1"


def free_port() -> int:
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return int(s.getsockname()[1])


class Restartable:
    """``grippers sim ARGS`` that can be killed (SIGKILL: no goodbye, like a power cut) and started again."""

    def __init__(self, *args: str) -> None:
        self.args = args
        self.sim: SimProcess | None = SimProcess(*args)
        self.url = self.sim.url

    def kill(self) -> None:
        assert self.sim is not None
        self.sim.proc.kill()
        self.sim.proc.wait(timeout=5)
        self.sim.close()
        self.sim = None

    def start(self) -> None:
        assert self.sim is None
        self.sim = SimProcess(*self.args)

    def close(self) -> None:
        if self.sim is not None:
            self.sim.close()
            self.sim = None


@pytest.fixture
def restartable() -> Iterator[Callable[..., Restartable]]:
    with closed_after(Restartable) as start:
        yield start


@pytest.fixture
def wsg_port_sim(restartable: Callable[..., Restartable]) -> Restartable:
    return restartable("wsg", "--listen", f"tcp://127.0.0.1:{free_port()}", "--time-scale", "20")


__all__ = ["FAST", "Restartable", "free_port"]
