"""The errors users catch: the drivers' hierarchy plus those that only the API layer raises."""

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

from .units import to_mm

__all__ = [
    "AccessDenied",
    "CommandFailed",
    "GripperWarning",
    "ProfileAssumed",
    "ConnectionLost",
    "DeviceMismatch",
    "FastStopActive",
    "FastStopForgotten",
    "GripperError",
    "GripperTimeout",
    "LimitError",
    "MotionBlocked",
    "NotReferenced",
    "NotSupported",
    "ProfileError",
    "ProtocolError",
    "ServerBusy",
    "URLError",
]


class FastStopActive(GripperError):
    """A fast stop (WSG FAST STOP, MSG e-stop) is active: motion is refused until ``acknowledge()``."""


class NotReferenced(CommandFailed):
    """A motion asked of a gripper whose axis is not referenced: call ``home()`` first.

    One error on every family for the same fact (issue 31 §1): the WSG answers E_NOT_INITIALIZED (its
    ``status`` is kept), an MSG that was not calibrated ignores the motion frame and used to be reported as
    "move aborted: the jaws stopped ... stalled". The message names the command the user called (a
    ``grasp`` says grasp). A :class:`CommandFailed`, so code that caught the device's refusal still does."""

    def __init__(
        self,
        message: str | None = None,
        *,
        status: int | None = None,
        status_name: str | None = None,
        device: str | None = None,
        command: str | None = None,
    ) -> None:
        if message is None:
            said = f" ({status_name})" if status_name else ""  # the device's own word, for logs and searches
            what = command or "the motion"
            message = f"{what} refused: the gripper is not referenced; call home() first{said}"
        super().__init__(message, status=status, status_name=status_name, device=device, command=command)

    def renamed(self, command: str) -> NotReferenced:
        """The same refusal named after the command the user called (a grasp's opening move is the grasp)."""
        error = NotReferenced(
            status=self.status, status_name=self.status_name, device=self.device, command=command
        )
        error.__cause__ = self
        return error


class MotionBlocked(CommandFailed):
    """A ``move()`` or ``release()`` stopped by an obstacle short of its target; ``width`` (m) says where the
    jaws stopped.

    An error, not a result, on every family (issue 31 §1: the WSG raised E_AXIS_BLOCKED, the MSG returned
    success with ``state=HOLDING``): a move that silently ends short lets a program go on believing the jaws
    are where it asked, and the next step (an insertion, a camera pose) then fails somewhere else. A
    ``grasp()`` is not affected: meeting a part is what a grasp is for. A :class:`CommandFailed`, so code
    that caught the WSG's refusal still does (its ``status`` is kept)."""

    MARGIN = 0.001
    """m: jaws stopped by an obstacle within this distance of the target reached it (they touch the part
    where they were sent; an MSG position byte is about 0.3 mm): no error, on every family."""

    def __init__(
        self,
        message: str | None = None,
        *,
        width: float | None = None,
        target: float | None = None,
        status: int | None = None,
        status_name: str | None = None,
        device: str | None = None,
        command: str | None = None,
    ) -> None:
        self.width = width
        self.target = target
        if message is None:
            where = "" if width is None else f" at {to_mm(width):.1f} mm"
            short = "" if target is None else f", short of its target {to_mm(target):g} mm"
            said = f" ({status_name})" if status_name else ""
            message = f"{command or 'the motion'} blocked by an obstacle{where}{short}{said}"
        super().__init__(message, status=status, status_name=status_name, device=device, command=command)

    def renamed(self, command: str) -> MotionBlocked:
        """The same stop named after the command the user called."""
        error = MotionBlocked(
            width=self.width,
            target=self.target,
            status=self.status,
            status_name=self.status_name,
            device=self.device,
            command=command,
        )
        error.__cause__ = self
        return error


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


class ServerBusy(GripperError):
    """A served gripper (``zenoh://``) refused the request unqueued: too many requests of clients that do not
    hold the lease are queued already. Nothing was done; try again (issue 43 §4: it arrived as a plain
    GripperError, so a program could not tell it from a device's refusal)."""


class GripperWarning(UserWarning):
    """Something the library assumed or worked around that the user should know about; the CLI prints each one
    as a ``warning:`` line on stderr and lists it in its ``--json`` documents."""


class ProfileAssumed(GripperWarning):
    """A gripper opened without a profile, whose device cannot report its model (an MSG does not know its rail
    length): the library took a default model, so widths are right only if that is the model on the bench.
    Pass ``profile=`` (``--profile`` on the command line) to silence it."""


class FastStopForgotten(GripperWarning):
    """A gripper closed while its fast stop was latched, on a device that keeps no fast-stop latch of its own
    (a Robotiq: its registers have no such state). The latch lived in this gripper only: the next program or
    command that opens the device can move it without an ``acknowledge()`` (issue 39 §2). The CLI prints it
    after ``grippers stop URL --fast``."""
