"""Timeouts and their bounds: the one home of the numbers every layer above the drivers shares (issue 32 §4).

A family's own exchange timeout is its profile's ``transport.timeout_s`` (the profile model's default, like
its ports and baud rate); what is here is what is the same for every family: the bound no timeout may pass
(checked by the profile models, by ``?timeout=`` and the other URL settings, and by the CLI through them) and
the default of callers that wait on something no profile describes (the CLI's ``--timeout``, a served
gripper). Imports nothing, so the CLI reads it without loading pydantic.
"""

from __future__ import annotations

# An exchange, a retry or a heartbeat an hour apart is no longer one: beyond it a timer overflows (1e308 s
# was an OverflowError from a condition's wait) long before a user would notice the difference.
MAX_TIMEOUT_S = 3600.0

# What the CLI waits per exchange (per device, for ``probe``) when ``--timeout`` is not given.
DEFAULT_TIMEOUT_S = 2.0

# The least exchange timeout of an in-process simulator (``sim://``) when none is given: the simulator's
# thread shares the process, and its interpreter lock, with the client, so on a loaded host its answers come
# late by the host's scheduling, which a device's never do (busy CI runs saw an MSG's 0.5 s bound overrun
# this way, docs/reliability.md). A profile's longer timeout stands; ``timeout=`` sets it as on hardware.
SIM_MIN_TIMEOUT_S = 2.0
