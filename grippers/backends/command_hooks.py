"""What a family offers the commands besides ``open()``: one object, :class:`CommandHooks` (issue 40 §2).

``grippers probe``, ``monitor``, ``settings``, ``selftest``, ``sim`` and ``doctor`` ask a family for more than
a gripper: where to look for its devices, how to read its frames, what it stores, what its self-test adds.
A family offers all of it as one attribute of its backend, ``commands``, an instance of a
:class:`CommandHooks` subclass that overrides only what it has; every hook has a default, and the defaults
derive what they can (the probe's candidates and the "did you mean" forms from the transports of the
family's profile URLs; a self-test of the contract's own motions needs nothing at all). A backend without
``commands`` gets the defaults. :func:`commands_of` is the one lookup, and the values the hooks take and
return (:class:`ProbeCandidate`, :class:`RawProbe`, :class:`Identity`, :class:`Dissector`) are here too.
docs/backends.md ("Hooks the commands call") describes every member; tests/test_hooks_documented.py fails
when one is not described there.
"""

from __future__ import annotations

import argparse
from collections.abc import Callable
from dataclasses import dataclass
from typing import Any, Protocol

# The bare transports whose URL a family's default probe candidate can be built from: one address, no node
# ids to guess (a CAN frame on ids nobody declared could be another device's command).
_DERIVED_TRANSPORTS = ("tcp", "udp", "serial")


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


def bus_query(options: dict[str, Any]) -> str:
    """The ``&k=v`` a CAN probe candidate's URL carries for the bus options of the probed URL (``options
    ["bus"]``: ``?port=`` of a udp_multicast bus, the bit rate): every family's candidates stay on the bus the
    user named (issue 33 §3: dropping ``port=`` searched python-can's default port and found another process's
    nodes)."""
    return "".join(f"&{k}={v}" for k, v in (options.get("bus") or {}).items())


class SimCommand(Protocol):
    """A family's own ``grippers sim`` (its ``sim_command()`` hook): its options and its run."""

    def add_arguments(self, parser: argparse.ArgumentParser) -> None: ...

    def run(self, args: argparse.Namespace, backend: Any) -> int: ...


class CommandHooks:
    """Everything the commands ask of a family, each with a default (docs/backends.md describes each).

    Subclass it, override what the family has, and offer an instance as the backend's ``commands``. The
    commands call :meth:`bind` (through :func:`commands_of`) before any hook, so a default can read the
    family (``self.family``) and its backend (``self.backend``)."""

    # grippers sim: the profile simulated without --model, the command's help and example lines, the further
    # names it answers to (`grippers sim msg` for the stepfoc family). None: the family's first profile, words
    # that fit every family.
    default_profile: str | None = None
    sim_help: str | None = None
    sim_example: str | None = None
    sim_names: tuple[str, ...] = ()
    # grippers probe (the machine scan) and doctor: where a device of the family answers out of the box.
    factory_address: str | None = None
    # The rank of the default probe candidates and "did you mean" forms among every family's (lower first).
    probe_order: int = 50
    # grippers settings: the options it takes ("tag", "force_limit", ...; docs/backends.md lists them).
    settings_options: tuple[str, ...] = ()
    # grippers selftest: True when info().limits.stroke is the device's own word (compared with the profile).
    reports_stroke: bool = False

    backend: Any = None

    def bind(self, backend: Any) -> None:
        """Called by :func:`commands_of` before the hooks are used: the backend they serve."""
        self.backend = backend

    @property
    def family(self) -> str:
        return str(getattr(self.backend, "family", ""))

    # --- grippers probe and the "did you mean" of a bare transport ---------------------------------------

    def profile_transports(self) -> tuple[str, ...]:
        """The transports of the family's profile URLs (``acme+tcp://…`` gives ``tcp``), which the default
        probe candidates and forms use. Read once, when first asked."""
        cached: tuple[str, ...] | None = getattr(self, "_transports", None)
        if cached is None:
            from grippers.errors import URLError
            from grippers.profiles import list_profiles
            from grippers.urls import parse_url

            found: list[str] = []
            for profile in list_profiles():
                if profile.family == self.family and profile.url:
                    try:
                        found.append(parse_url(profile.url).transport)
                    except URLError:
                        continue
            cached = tuple(dict.fromkeys(found))
            self._transports = cached
        return cached

    def bare_forms(self) -> dict[str, tuple[int, str]]:
        """Bare transport -> (rank, family URL form with ``{rest}``): the "did you mean" of ``tcp://HOST``.
        Default: the family's URL on each transport of its profiles (``probe_order`` the rank)."""
        return {
            t: (self.probe_order, f"{self.family}+{t}://{{rest}}")
            for t in self.profile_transports()
            if t in _DERIVED_TRANSPORTS
        }

    def probe_candidates(self, transport: str, where: Any, options: dict[str, Any]) -> list[ProbeCandidate]:
        """The family URLs ``grippers probe`` tries on a bare transport. Default: the same address as a URL of
        the family, on a TCP, UDP or serial transport its profiles use (the port as given, or the one
        ``open()`` defaults to); none on CAN."""
        from grippers.urls import format_host

        if transport not in self.profile_transports() or transport not in _DERIVED_TRANSPORTS:
            return []
        if transport == "serial":
            rest = where.serial_port or ""
        elif where.host:
            rest = format_host(where.host, where.port)
        else:
            return []
        return [ProbeCandidate(f"{self.family}+{transport}://{rest}", order=self.probe_order)]

    def probe_identity(self, gripper: Any) -> Identity | None:
        """Whether an opened device is the family's own (several families answered on one port). Default:
        None, no check."""
        return None

    def raw_probe(self, transport: str) -> RawProbe | None:
        """What to send on a raw connection after a silent open on ``transport``. Default: nothing."""
        return None

    # --- grippers monitor ---------------------------------------------------------------------------------

    def dissector(self) -> Dissector | None:
        """The family's frame readers for ``grippers monitor``. Default: None (none: it is not dissected)."""
        return None

    # --- grippers settings and selftest ---------------------------------------------------------------------

    def local(self, gripper: Any) -> bool:
        """Whether ``gripper``'s device client is in this process, opened by this family (False for a
        served gripper: its settings and the family's self-test lines stay on the serving machine)."""
        from grippers.errors import URLError
        from grippers.urls import parse_url

        try:
            return bool(self.family) and parse_url(gripper.url).family == self.family
        except URLError:
            return False

    def read_settings(self, gripper: Any) -> dict[str, Any] | None:
        """The stored settings by name (``grippers settings``, printed and the JSON's ``settings``). Default:
        None, the family offers no device settings."""
        return None

    def check_settings(self, gripper: Any, args: argparse.Namespace) -> None:
        """Refuse a bad option value before anything is written (a :class:`grippers.LimitError`)."""

    def change_settings(self, gripper: Any, args: argparse.Namespace, changed: list[str]) -> str | None:
        """Write what ``args`` asks, appending each changed name to ``changed``; the URL the device answers
        at afterwards when that changed (a new CAN node id), else None."""
        return None

    def selftest_checks(self, gripper: Any, add: Callable[..., None]) -> None:
        """The family's own ``grippers selftest`` lines, after the generic motions. Default: none."""

    # --- grippers sim -------------------------------------------------------------------------------------

    def sim_command(self) -> SimCommand | None:
        """The family's own ``grippers sim`` (its options and run). Default: None, the generic command over
        the backend's ``simulator()``."""
        return None


_defaults: dict[str, CommandHooks] = {}


def commands_of(backend: Any) -> CommandHooks:
    """The command hooks of ``backend`` (its ``commands``, or the defaults; None, an unknown family: the
    defaults of no family), bound to it. The one lookup every command makes."""
    hooks = getattr(backend, "commands", None) if backend is not None else None
    if hooks is None:
        family = str(getattr(backend, "family", ""))
        hooks = _defaults.get(family)
        if hooks is None:
            hooks = _defaults[family] = CommandHooks()
    if not isinstance(hooks, CommandHooks):
        raise TypeError(f"the {getattr(backend, 'family', '?')} backend's commands is not a CommandHooks")
    hooks.bind(backend)
    return hooks
