"""``gripper_sim``: simulated grippers for a user's own pytest suite (the pytest plugin ``grippers``).

A test asks for the fixture and calls it with a built-in profile name (or a profile file); a simulator of that
gripper starts over a real transport (loopback TCP for a WSG, a python-can ``virtual`` bus for an MSG, unless
``transport=`` says otherwise) and is stopped after the test::

    def test_pick(gripper_sim):
        url = gripper_sim("wsg50", part_width_mm=40)
        with grippers.open(url) as g:
            g.home()
            assert g.grasp(0.04).grasped

The URL names the profile (``?profile=``), so the code under test opens it like hardware. ``url.simulator`` is
the simulator itself, for fault hooks and parts. Keywords are the ``sim://`` settings (``time_scale``,
``part_width_mm``, ``transport``, ``firmware``, …); a misspelt one is a :class:`~grippers.URLError`. At the
end of the test the fixture fails it if a simulator's thread died: a crash in the simulator must not pass for
a gripper that stopped answering.

The plugin is registered through the ``pytest11`` entry point in pyproject.toml, so installing the package
is all a suite needs; importing this module is cheap (the simulators load when first asked for).

:mod:`grippers.testing.conformance` is the backend conformance suite built on this fixture's simulators: a
family's own tests subclass its ``ConformanceSuite`` (docs/backends.md, "Conformance suite").
"""

from __future__ import annotations

import os
from collections.abc import Iterator
from typing import Any

import pytest

__all__ = ["GripperSims", "SimURL", "gripper_sim"]


class SimURL(str):
    """A connection URL that also carries the simulator serving it (``.simulator``).

    ``grippers.open`` gives a gripper opened on one, as on ``sim://``, an exchange timeout of at least
    ``grippers.timeouts.SIM_MIN_TIMEOUT_S`` when none is given: the simulator shares this process's CPU."""

    simulator: Any

    @classmethod
    def serving(cls, text: str, simulator: Any) -> SimURL:
        """``text``, marked as served by ``simulator`` in this process."""
        url = cls(text)
        url.simulator = simulator
        return url


class GripperSims:
    """What the ``gripper_sim`` fixture gives: call it to start a simulator; all are stopped at the end."""

    def __init__(self) -> None:
        self.servers: list[Any] = []

    def __call__(self, profile: str | os.PathLike[str] = "wsg50", **settings: Any) -> SimURL:
        from ..backends import get_backend
        from ..drivers.urls import append_params
        from ..errors import URLError
        from ..profiles import load_profile
        from ..settings import Settings

        chosen = load_profile(profile)
        backend = get_backend(chosen.family)
        if not hasattr(backend, "simulator"):
            raise URLError(f"gripper_sim: the {chosen.family!r} backend has no simulator")
        where = f"gripper_sim({chosen.name!r})"
        given = Settings(where, {}, {k: v for k, v in settings.items() if v is not None})
        server = backend.simulator(chosen, given)
        self.servers.append(server)
        # What the simulator did not take was misspelt (the node it serves is already in the server's URL).
        unknown = sorted(k for k in settings if k not in given.taken)
        if unknown:
            raise URLError(f"{where}: unknown setting(s) {', '.join(unknown)}")
        return SimURL.serving(append_params(server.url, {"profile": chosen.name}), server)

    def close(self) -> list[str]:
        """Stop every simulator; returns what went wrong in them (a thread that died), one line each."""
        problems = []
        for server in self.servers:
            server.close()
            error = getattr(server, "error", None)
            if error is not None:
                problems.append(f"{server.url}: simulator thread died: {error!r}")
        self.servers.clear()
        return problems


@pytest.fixture
def gripper_sim() -> Iterator[GripperSims]:
    """``gripper_sim("wsg50", part_width_mm=40)`` starts a simulated gripper and returns its URL."""
    sims = GripperSims()
    yield sims
    problems = sims.close()
    if problems:
        pytest.fail("; ".join(problems), pytrace=False)
