"""The errors users catch: the drivers' hierarchy plus the two that only the API layer raises."""

from __future__ import annotations

from grippers.drivers.errors import (
    CommandFailed,
    ConnectionLost,
    GripperError,
    GripperTimeout,
    LimitError,
    NotSupported,
    ProtocolError,
)

__all__ = [
    "CommandFailed",
    "ConnectionLost",
    "GripperError",
    "GripperTimeout",
    "LimitError",
    "NotSupported",
    "ProfileError",
    "ProtocolError",
    "URLError",
]


class ProfileError(GripperError, ValueError):
    """A profile not found or failing validation; the message names the file, the field and the rule."""


class URLError(GripperError, ValueError):
    """A connection URL that does not follow the grammar in :mod:`grippers.urls`."""
