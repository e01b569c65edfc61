"""Backends: one per device family, found like python-can finds its interfaces.

A backend adapts a driver to :class:`grippers.Gripper`. The built-in ones are named in
:data:`BUILTIN_BACKENDS` and imported only when used; third-party packages add a family by declaring an entry
point in the group ``grippers.backends`` (see docs/backends.md), with no change to this repository::

    [project.entry-points."grippers.backends"]
    acme = "acme_grippers:AcmeBackend"

A backend is any object with ``family`` (the URL scheme's first part), ``profile_model`` (a
:class:`grippers.profiles.ProfileBase` subclass, or None to reuse a built-in family's), ``open(url, profile,
settings) -> Gripper`` and, optionally, ``simulator(profile, settings, listen=None)`` returning a running
simulator (an object with ``url`` and ``close()``) for ``sim://``, ``grippers sim`` and the tests. The
protocols below declare every call the API, the CLI and grippers.testing make on a backend.

Everything else a family offers the commands (the probe's candidates, the monitor's dissector, device
settings, self-test lines, its own ``grippers sim``) is one object, the backend's ``commands``: a
:class:`~grippers.backends.command_hooks.CommandHooks` (issue 40 §2; public as ``grippers.kit.CommandHooks``),
found by ``commands_of``, the one lookup. docs/backends.md ("Hooks the commands call") describes each hook,
and tests/test_hooks_documented.py fails when one is missing there. ``tests/test_vendor_neutral.py`` keeps the
rest of the package free of vendor names.
"""

from __future__ import annotations

import importlib
from typing import TYPE_CHECKING, Any, Protocol

from ..errors import URLError

if TYPE_CHECKING:
    from ..drivers.urls import ConnectionURL
    from ..gripper import Gripper
    from ..profile_model import ProfileBase
    from ..settings import Settings

__all__ = [
    "BUILTIN_BACKENDS",
    "ENTRY_POINT_GROUP",
    "Backend",
    "BusSimulatedBackend",
    "SimServer",
    "SimulatedBackend",
    "available_backends",
    "find_backend",
    "get_backend",
]

ENTRY_POINT_GROUP = "grippers.backends"

# family -> "module:attribute", imported lazily (python-can's BACKENDS table is the model).
BUILTIN_BACKENDS: dict[str, str] = {
    "wsg": "grippers.backends.wsg:WsgBackend",
    "stepfoc": "grippers.backends.stepfoc:StepfocBackend",
    "robotiq": "grippers.backends.robotiq:RobotiqBackend",
    "schunk": "grippers.backends.schunk:SchunkBackend",
    "zenoh": "grippers.remote.client:ZenohBackend",  # served grippers (docs/remote.md); needs [remote]
}


class Backend(Protocol):
    """What :func:`grippers.open` needs of a family: its name, its profile model and a way to connect."""

    family: str
    profile_model: type[ProfileBase] | None

    def open(self, url: ConnectionURL, profile: ProfileBase | None, settings: Settings) -> Gripper: ...


class SimulatedBackend(Backend, Protocol):
    """A family with a simulator: ``sim://``, ``grippers sim`` and the ``gripper_sim`` fixture call
    :meth:`simulator`, which serves where ``listen`` says, or on the family's default transport (None)."""

    def simulator(self, profile: ProfileBase, settings: Settings, listen: str | None = None) -> SimServer: ...


class BusSimulatedBackend(SimulatedBackend, Protocol):
    """A family whose simulator serves several nodes on one bus (``grippers sim msg --nodes``)."""

    def sim_model(self, profile: ProfileBase, node: int, part_width_mm: float | None) -> Any: ...

    def serve(self, models: list[Any], listen: str, settings: Settings) -> SimServer: ...


class SimServer(Protocol):
    """A running simulator: where to connect, and how to stop it."""

    url: str

    def close(self) -> None: ...


_cache: dict[str, Any] = {}


def _load(spec: str) -> Any:
    module_name, _, attribute = spec.partition(":")
    obj = getattr(importlib.import_module(module_name), attribute)
    return obj() if isinstance(obj, type) else obj


def _plugin_specs() -> dict[str, Any]:
    from importlib.metadata import entry_points  # ~30 ms: only when a family is looked up, never at --help

    return {ep.name: ep for ep in entry_points(group=ENTRY_POINT_GROUP)}


def available_backends() -> list[str]:
    return sorted(set(BUILTIN_BACKENDS) | set(_plugin_specs()))


def find_backend(family: str) -> Any | None:
    """The backend of ``family``, or None when neither built in nor installed as a plugin."""
    if family in _cache:
        return _cache[family]
    if family in BUILTIN_BACKENDS:
        backend = _load(BUILTIN_BACKENDS[family])
    else:
        ep = _plugin_specs().get(family)
        if ep is None:
            return None
        obj = ep.load()
        backend = obj() if isinstance(obj, type) else obj
    _cache[family] = backend
    return backend


def get_backend(family: str) -> Any:
    backend = find_backend(family)
    if backend is None:
        # An unknown family is almost always a typo in the URL, so it is a URL error (and a ValueError).
        raise URLError(
            f"no backend for family {family!r} (available: {', '.join(available_backends())}; "
            f"plugins register in the entry-point group {ENTRY_POINT_GROUP!r})"
        )
    return backend
