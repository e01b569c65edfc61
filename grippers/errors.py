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
    URLError,
)

__all__ = [
    "AccessDenied",
    "CommandFailed",
    "GripperWarning",
    "ProfileAssumed",
    "ConnectionLost",
    "DeviceMismatch",
    "FastStopActive",
    "GripperError",
    "GripperTimeout",
    "LimitError",
    "NotSupported",
    "ProfileError",
    "ProtocolError",
    "URLError",
]


class FastStopActive(GripperError):
    """A fast stop (WSG FAST STOP, MSG e-stop) is active: motion is refused until ``acknowledge()``."""


class DeviceMismatch(ConnectionLost):
    """Another device answers where the gripper was (``reconnect=true``): it is refused, never driven with the
    limits of the one that was opened. A :class:`ConnectionLost`: to the caller the opened gripper is gone."""


class ProfileError(GripperError, ValueError):
    """A profile not found or failing validation; the message names the file, the field and the rule."""


class AccessDenied(GripperError):
    """Another client holds the control lease of a served gripper (``zenoh://``); ``holder`` names it.
    ``stop()`` and ``fast_stop()`` are never denied."""

    def __init__(
        self,
        message: str,
        *,
        holder: str | None = None,
        device: str | None = None,
        command: str | None = None,
    ) -> None:
        self.holder = holder
        super().__init__(message, device=device, command=command)


class GripperWarning(UserWarning):
    """Something the library assumed or worked around that the user should know about; the CLI prints each one
    as a ``warning:`` line on stderr and lists it in its ``--json`` documents."""


class ProfileAssumed(GripperWarning):
    """A gripper opened without a profile, whose device cannot report its model (an MSG does not know its rail
    length): the library took a default model, so widths are right only if that is the model on the bench.
    Pass ``profile=`` (``--profile`` on the command line) to silence it."""
