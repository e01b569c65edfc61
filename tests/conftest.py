"""Shared test settings.

Hypothesis runs a bounded number of examples so CI stays fast; ``GRIPPERS_FUZZ=long`` switches to the
on-demand long mode (see docs/reliability.md).
"""

from __future__ import annotations

import os

import pytest
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
LONG = os.environ.get("GRIPPERS_FUZZ") == "long"
settings.load_profile("long" if LONG else "ci")
# GRIPPERS_FUZZ_EXAMPLES=N sets the long mode's count, for a long run of chosen targets (a million examples of
# the slow ones takes half an hour on 2 cores).
if LONG and os.environ.get("GRIPPERS_FUZZ_EXAMPLES"):
    settings.register_profile(
        "long-n", settings.get_profile("long"), max_examples=int(os.environ["GRIPPERS_FUZZ_EXAMPLES"])
    )
    settings.load_profile("long-n")


def pytest_collection_modifyitems(items: list[pytest.Item]) -> None:
    """Long mode: no pytest-timeout (120 s in pyproject.toml); a million examples take many minutes."""
    if LONG:
        for item in items:
            item.add_marker(pytest.mark.timeout(0))
