"""Backends: one per device family, found like python-can finds its interfaces.

A backend adapts a driver to :class:`grippers.Gripper`. The built-in ones are named in
:data:`BUILTIN_BACKENDS` and imported only when used; third-party packages add a family by declaring an entry
point in the group ``grippers.backends`` (see docs/backends.md), with no change to this repository::

    [project.entry-points."grippers.backends"]
    acme = "acme_grippers:AcmeBackend"

A backend is any object with ``family`` (the URL scheme's first part), ``profile_model`` (a
:class:`grippers.profiles.ProfileBase` subclass, or None to reuse a built-in family's), ``open(url, profile,
settings) -> Gripper`` and, optionally, ``simulate(profile, settings)`` returning a running simulator (an
object with ``url`` and ``close()``) for ``sim://``. The protocols below declare every call the API, the CLI
and grippers.testing make on a backend.

Everything else a family knows, the CLI asks through :func:`hook` (issue 28 §2: no generic module names a
family): ``probe_candidates``, ``probe_identity``, ``raw_probe``, ``factory_address``, ``bare_forms``,
``dissector``, ``device_settings``, ``selftest_checks``, ``reports_stroke``, ``cli_sim`` (or ``sim_help``,
``sim_example``, ``default_profile``). A family declares them in its CLI module (``X_cli`` beside its
backend's module ``X``) or on its backend; one it lacks is a command that says, in words that fit every
family, that it is not offered. docs/backends.md ("Hooks the commands call") describes each, and
tests/test_hooks_documented.py fails when a name asked here is missing there. ``tests/test_vendor_neutral.py``
keeps the rest of the package free of vendor names.
"""

from __future__ import annotations

import importlib
from collections.abc import Callable
from dataclasses import dataclass
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
    "Dissector",
    "Identity",
    "ProbeCandidate",
    "RawProbe",
    "SimServer",
    "SimulatedBackend",
    "available_backends",
    "bus_query",
    "find_backend",
    "get_backend",
    "hook",
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
    """A family with a simulator: ``sim://`` (:meth:`simulate`), ``grippers sim`` and the ``gripper_sim``
    fixture (:meth:`simulator`, which serves where ``listen`` says, or on the family's default transport)."""

    def simulate(self, profile: ProfileBase, settings: Settings) -> SimServer: ...

    def simulator(self, profile: ProfileBase, settings: Settings, listen: str | None = None) -> SimServer: ...


class BusSimulatedBackend(SimulatedBackend, Protocol):
    """A family whose simulator serves several nodes on one bus (``grippers sim msg --nodes``)."""

    def sim_model(self, profile: ProfileBase, node: int, part_width_mm: float | None) -> Any: ...

    def serve(self, models: list[Any], listen: str, settings: Settings) -> SimServer: ...


@dataclass(frozen=True)
class Dissector:
    """What a family's ``dissector()`` hook gives ``grippers monitor`` (issue 28 §2): its protocol's name,
    and the readers it has: ``stream()`` for a byte stream (a capture, the TCP proxy), ``can(options)`` for
    CAN frames (``options``: ``only`` when ``--protocol`` names it, ``can_id`` from ``--can-id``, the command
    id of a family whose replies come on the next id), and the device's TCP port for the proxy.
    ``bytes_default``: the reader of a byte capture when none is named.
    ``finds(data)``: whether a run of bytes holds one of the family's packets (``monitor`` tells a raw
    capture without line ends from a file that is no capture at all)."""

    protocol: str
    stream: Callable[[], Any] | None = None
    can: Callable[[dict[str, Any]], Any] | None = None
    tcp_port: int | None = None
    bytes_default: bool = False
    finds: Callable[[bytes], bool] | None = None


@dataclass(frozen=True)
class ProbeCandidate:
    """One URL a family's ``probe_candidates(transport, where, options)`` hook offers for a bare transport
    (``grippers probe tcp://HOST``, a serial port, a CAN bus). Candidates sharing a serial port are tried
    in ``order``; ``unless_nodes``: tried only when no node answered at these bus nodes (a frame that would
    be another family's E-stop there). ``protocol``: the wire protocol the candidate speaks
    (``"modbus-rtu"``); once a candidate answers on a serial port, the others of the same protocol are
    tried there too (they would answer as well), and the families' ``probe_identity`` checks decide which
    of them the device is (issue 40 §4). None: the first to answer claims the port."""

    url: str
    order: int = 50
    unless_nodes: tuple[int, ...] = ()
    protocol: str | None = None


@dataclass(frozen=True)
class Identity:
    """What a family's ``probe_identity(gripper)`` hook says of a device that opened as its own: ``mine``
    True (what it read back is the family's: a model register, a vendor string), False (it read back
    something that is not: the device only speaks the same protocol) or None (nothing it reads tells its
    devices from another family's); ``reason`` says what it read, for the probe's output."""

    mine: bool | None
    reason: str


def bus_query(options: dict[str, Any]) -> str:
    """The ``&k=v`` a CAN probe candidate's URL carries for the bus options of the probed URL (``options
    ["bus"]``: ``?port=`` of a udp_multicast bus, the bit rate): every family's candidates stay on the bus the
    user named (issue 33 §3: dropping ``port=`` searched python-can's default port and found another process's
    nodes)."""
    return "".join(f"&{k}={v}" for k, v in (options.get("bus") or {}).items())


@dataclass(frozen=True)
class RawProbe:
    """A family's ``raw_probe(transport)`` hook: after a silent open, ``grippers probe`` sends ``request`` on
    a raw connection and tells a device that answers garbage (another protocol, baud rate) from a silent
    one. ``goodbye`` is sent after (a device on TCP that must not be left stopped); ``is_answer(received)``:
    bytes that are the family's (a late answer: the timeout stands); ``port``: for a URL without one."""

    request: bytes
    goodbye: bytes = b""
    is_answer: Callable[[bytes], bool] | None = None
    port: int | None = None


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


def hook(backend: Any, name: str) -> Any:
    """The hook ``name`` a family offers the CLI (``dissector``, ``probe_candidates``, ``factory_address``,
    ``device_settings``, ``selftest_checks``, ``cli_sim``, ...), or None when it offers none.

    A family declares a hook in its CLI module, the module ``X_cli`` beside its backend's module ``X``
    (``grippers.backends.acme`` -> ``grippers.backends.acme_cli``), or as an attribute of its backend; the CLI
    module's wins, so the command-line side of a family lives in one file apart from the device code. A
    backend defined in a top-level module has no CLI module: its attributes are its hooks.
    """
    module = _cli_module(type(backend).__module__)
    if module is not None and hasattr(module, name):
        return getattr(module, name)
    return getattr(backend, name, None)


_cli_modules: dict[str, Any] = {}


def _cli_module(backend_module: str) -> Any:
    if "." not in backend_module:
        return None
    if backend_module not in _cli_modules:
        name = backend_module + "_cli"
        try:
            _cli_modules[backend_module] = importlib.import_module(name)
        except ModuleNotFoundError as exc:
            if exc.name != name:  # the CLI module exists and lacks a dependency: that is its error
                raise
            _cli_modules[backend_module] = None
    return _cli_modules[backend_module]


def get_backend(family: str) -> Any:
    backend = find_backend(family)
    if backend is None:
        # An unknown family is almost always a typo in the URL, so it is a URL error (and a ValueError).
        raise URLError(
            f"no backend for family {family!r} (available: {', '.join(available_backends())}; "
            f"plugins register in the entry-point group {ENTRY_POINT_GROUP!r})"
        )
    return backend
