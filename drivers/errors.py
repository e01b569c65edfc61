"""The one exception hierarchy shared by every driver and re-exported by :mod:`grippers`.

It lives in ``drivers`` (not ``grippers``) so drivers can raise the exceptions users catch without importing
the layer above them. Each class also inherits the built-in exception a user would already catch, the way
python-can's ``CanTimeoutError`` is a ``TimeoutError``.
"""

from __future__ import annotations


class GripperError(Exception):
    """Base of every error this library raises.

    ``device`` names the gripper (a URL, address or node), ``command`` the command that failed; both are
    optional so an error can be raised before a device or command is known.
    """

    def __init__(self, message: str, *, device: str | None = None, command: str | None = None) -> None:
        self.device = device
        self.command = command
        self.message = message
        parts = []
        if device:
            parts.append(device)
        if command:
            parts.append(command)
        prefix = ": ".join(parts)
        super().__init__(f"{prefix}: {message}" if prefix else message)


class GripperTimeout(GripperError, TimeoutError):
    """No answer within the timeout. Also a :class:`TimeoutError`."""


class ConnectionLost(GripperError, ConnectionError):
    """The transport failed or closed. Also a :class:`ConnectionError`."""


class CommandFailed(GripperError):
    """The device refused or failed a command; carries the device's status code and its name."""

    def __init__(
        self,
        message: str,
        *,
        status: int | None = None,
        status_name: str | None = None,
        device: str | None = None,
        command: str | None = None,
    ) -> None:
        self.status = status
        self.status_name = status_name
        super().__init__(message, device=device, command=command)


class LimitError(GripperError, ValueError):
    """A value outside the device's or profile's limits, refused before anything was sent."""


class NotSupported(GripperError):
    """The device (model, firmware or transport) cannot do this; refused locally."""


class ProtocolError(GripperError):
    """Bytes or frames that do not decode: wrong length, bad checksum, unknown layout."""


class URLError(GripperError, ValueError):
    """A connection URL that does not follow the grammar in ``drivers/urls.py`` (:mod:`grippers.urls`), or a
    setting out of its range; also a :class:`ValueError`."""
