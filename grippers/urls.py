"""The connection-URL grammar, as the API names it.

::

    wsg+tcp://HOST[:PORT]                    wsg+udp://HOST[:PORT][?local_port=N]
    wsg+serial://PORT-OR-PYSERIAL-URL[?baudrate=N&stopbits=2]
    wsg+can://INTERFACE/CHANNEL[?bitrate=N&send_id=0x000&recv_id=0x001]
    stepfoc+can://INTERFACE/CHANNEL[?node=N&bitrate=N]      stepfoc+serial://PORT[?baudrate=N]
    robotiq+serial://PORT[?slave=9]         robotiq+tcp://HOST[:54321][?slave=9]   (54321: a UR forwarder)
    robotiq+tcp://HOST:63352                 (Robotiq's URCap socket; or ?protocol=urcap)
    sim://PROFILE[?part_width_mm=40&transport=tcp]          (an in-process simulated gripper)
    zenoh://NAME?connect=tcp/HOST:7447                       (a gripper served by `grippers serve`)

The parser itself is ``drivers/urls.py`` (:mod:`grippers.drivers.urls`), where the drivers, the simulators and
the CLI read URLs too: one grammar, no second parser here. Its docstring has the rules.
Query parameters become settings that win over the profile's fields (keyword overrides to
:func:`grippers.open` win over both). Numeric settings are range-checked where a backend takes them
(``grippers/settings.py``, ``RANGES``): a port of 70000 or a timeout of 1e10 s is a :class:`URLError` at open,
before anything is sent.
"""

from __future__ import annotations

from grippers.drivers.urls import (
    TRANSPORTS,
    ConnectionURL,
    format_host,
    is_url,
    parse_query,
    parse_url,
    refuse_unknown,
    to_bool,
    to_float,
    to_int,
)

from .errors import URLError

__all__ = [
    "TRANSPORTS",
    "ConnectionURL",
    "URLError",
    "format_host",
    "is_url",
    "parse_query",
    "parse_url",
    "refuse_unknown",
    "to_bool",
    "to_float",
    "to_int",
]
