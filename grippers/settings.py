"""Connection settings from three layers, so the precedence rule lives in one place.

Profile fields are the defaults; query parameters of the URL win over them; keyword overrides to
open() win over both. A backend *takes* each setting it understands; whatever is left when it is
done was misspelt or meant for another family, and is refused with the list of what is understood.
"""

from __future__ import annotations

from collections.abc import Callable
from typing import Any, TypeVar, cast

from grippers.drivers.urls import refuse_unknown, to_bool, to_float, to_int

from .errors import URLError
from .timeouts import MAX_TIMEOUT_S

T = TypeVar("T")
_text = str  # the builtin, for use inside Settings (whose method ``str`` hides it in the class body)
_real = float  # likewise (its method ``float``)


# The range of every setting that has one, checked where it is taken, so a backend never hands a socket or a
# timer a value it cannot take (``local_port=70000`` was an OverflowError from bind(), ``timeout=1e10`` one
# from the clock). Names are the query parameters the backends take (the URL grammar is in grippers/urls.py);
# CAN ids are standard 11-bit identifiers, MSG nodes 0..15 (docs/protocols.md §2).
RANGES: dict[str, tuple[float, float]] = {
    "local_port": (0, 65535),
    "port": (1, 65535),
    "node": (0, 15),
    "slave": (1, 247),  # a Robotiq's Modbus slave id (9 by default)
    "send_id": (0, 0x7FF),
    "recv_id": (0, 0x7FF),
    "bitrate": (1, 10_000_000),
    "baudrate": (1, 10_000_000),
    "bytesize": (5, 8),
    "serial": (0, 0xFFFFFFFF),
    "timeout": (0, MAX_TIMEOUT_S),  # an exchange longer than an hour is not an exchange (grippers.timeouts)
    # The reconnection thread waits on a condition for these: 1e308 s overflowed it (OverflowError), and a
    # retry or heartbeat an hour apart is no longer a reconnection (grippers/reconnect.py).
    "reconnect_backoff_s": (0, MAX_TIMEOUT_S),
    "reconnect_backoff_max_s": (0, MAX_TIMEOUT_S),
    "heartbeat_s": (0, MAX_TIMEOUT_S),
    "time_scale": (0, 1_000_000.0),
    "part_width_mm": (0, 10_000.0),
    "clamping_travel_mm": (0, 10_000.0),
}


class Settings:
    def __init__(self, url: str, query: dict[str, str], overrides: dict[str, Any]) -> None:
        self.url = url
        self._values: dict[str, Any] = {**query, **overrides}
        self._known: set[str] = set()
        self._expected: set[str] = set()
        self._floors: dict[str, _real] = {}

    def _take(self, name: str, default: T, convert: Callable[[Any, str, str], T]) -> T:
        self._known.add(name)
        value = self._values.pop(name, None)
        if value is None:
            return self._floored(name, default)
        converted = convert(value, name, self.url)
        bounds = RANGES.get(name)
        if bounds is not None and isinstance(converted, int | float) and not isinstance(converted, bool):
            lo, hi = bounds
            if not lo <= converted <= hi:
                raise URLError(f"{self.url}: {name} must lie within {lo:g}..{hi:g}, not {value!r}")
        return converted

    def _floored(self, name: str, default: T) -> T:
        floor = self._floors.get(name)
        if floor is None or not isinstance(default, int | float) or isinstance(default, bool):
            return default
        return cast(T, max(default, floor))  # a number, as the default is

    def int(self, name: str, default: Any) -> Any:
        return self._take(name, default, to_int)

    def float(self, name: str, default: Any) -> Any:
        return self._take(name, default, to_float)

    def positive(self, name: str, default: Any) -> Any:
        """A number above zero (timeouts, time scales): 0 would fail every exchange at once, and a negative
        one too, with a misleading message (a TCP connect "in progress")."""
        value = self._take(name, default, to_float)
        if value is not None and value <= 0:
            raise URLError(f"{self.url}: {name} must be above 0, not {value!r}")
        return value

    def bool(self, name: str, default: Any) -> Any:
        return self._take(name, default, to_bool)

    def str(self, name: str, default: Any) -> Any:
        return self._take(name, default, lambda v, _n, _u: _text(v))

    @property
    def taken(self) -> frozenset[_text]:
        """The names a backend has asked for so far (whether or not they were given)."""
        return frozenset(self._known)

    def add_defaults(self, values: dict[_text, Any]) -> None:
        """Settings that apply unless the user gave their own (a simulator's URL parameters)."""
        for key, value in values.items():
            self._values.setdefault(key, value)

    def at_least(self, name: _text, floor: _real) -> None:
        """When the user gives no ``name``, the backend's default is raised to ``floor`` if below it (an
        in-process simulator's timeout: grippers.timeouts.SIM_MIN_TIMEOUT_S)."""
        self._floors[name] = floor

    def expect(self, *names: _text) -> None:
        """Names that are taken later, after the device answered (``reconnect=`` and its kin, taken once the
        gripper exists): known to :meth:`check` before they are taken."""
        self._expected.update(names)

    def check(self) -> None:
        """Refuse now what no one has taken and no one will: a backend calls this when it has taken its
        settings and before its first I/O (issue 31 §1: ``nod=3`` on a silent bus was reported as
        "poll: no reply" after the timeout, never as the URLError :func:`grippers.open` promises)."""
        self._refuse(set(self._values) - self._expected)

    def finish(self) -> None:
        """Refuse what no one took: a typo must not silently fall back to a default."""
        self._refuse(set(self._values))

    def _refuse(self, unknown: set[_text]) -> None:
        refuse_unknown(
            self.url,
            unknown,
            (self._known | self._expected) - unknown,
            what="setting(s)",
            known_as="this backend takes",
        )
