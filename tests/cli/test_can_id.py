"""The ``--can-id`` argument type shared by ``grippers probe`` and ``grippers monitor``."""

from __future__ import annotations

import argparse

import pytest

from grippers.cli.common import can_id


@pytest.mark.parametrize(("text", "value"), [("0", 0), ("0x7FF", 0x7FF), ("1", 1), ("0x001", 1)])
def test_every_standard_identifier_is_accepted(text: str, value: int) -> None:
    assert can_id(text) == value


@pytest.mark.parametrize("text", ["0x800", "-1", "one", ""])
def test_anything_else_is_a_usage_error(text: str) -> None:
    with pytest.raises(argparse.ArgumentTypeError):
        can_id(text)
