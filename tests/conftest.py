"""Shared test settings.

Hypothesis runs a bounded number of examples so CI stays fast; ``GRIPPERS_FUZZ=long`` switches to the
on-demand long mode (see docs/reliability.md).
"""

from __future__ import annotations

import os

from hypothesis import HealthCheck, settings

settings.register_profile(
    "ci",
    max_examples=150,
    deadline=None,
    suppress_health_check=[HealthCheck.too_slow],
)
settings.register_profile(
    "long",
    max_examples=1_000_000,
    deadline=None,
    suppress_health_check=list(HealthCheck),
)
settings.load_profile("long" if os.environ.get("GRIPPERS_FUZZ") == "long" else "ci")
