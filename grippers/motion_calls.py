"""What a motion call does around the device's primitive, apart from the motion rule (grippers/motions.py):
the refusal renamed after the command the user called, and the grasp that first makes room.

Functions used by :class:`~grippers.gripper.Gripper`, the same for every family.
"""

from __future__ import annotations

import logging
from collections.abc import Callable
from typing import TypeVar

from .device import Device
from .errors import GripperError, GripperTimeout, MotionBlocked, NotReferenced
from .fast_stop import FastStopLatch
from .motions import MotionSupervisor
from .profile_model import Limits
from .states import GraspResult

T = TypeVar("T")

log = logging.getLogger(__name__)

GRASP_CLEARANCE = 0.005  # m: where grasp() opens to when the jaws start inside the part's width


def named(name: str, device: str, call: Callable[[], T]) -> T:
    """``call()``, with its refusals and its timeout named after the command the user called and the
    gripper (``device``: ``PROFILE@URL``), the same on every family (issue 39 §2).

    A device raises them from the primitive it was in (a grasp's opening move is ``move``; the WSG names its
    wire command, ``PREPOSITION (21h)``, and its URL without the profile), and "call home() before move"
    after a ``grasp()``, or a ``timeout=`` ending named after a command the user never called, sends the user
    looking in the wrong place. The one place where a motion's ending is worded: the device's own words stay
    in the message (its wire command in parentheses) and as ``__cause__``."""
    try:
        return call()
    except (NotReferenced, MotionBlocked) as exc:
        if exc.command == name:
            raise
        raise exc.renamed(name) from exc
    except GripperTimeout as exc:
        if type(exc) is not GripperTimeout or (exc.command == name and exc.device == device):
            raise
        said = f" ({exc.command})" if exc.command and exc.command != name else ""
        raise GripperTimeout(f"{exc.message}{said}", device=device, command=name) from exc


def grasp_with_room(
    device: Device,
    limits: Limits,
    motions: MotionSupervisor,
    latch: FastStopLatch,
    args: tuple[float, float, float, float],
) -> GraspResult:
    """The grasp ``args`` (width, speed, force, timeout), after opening past the part when the jaws start
    inside its width (an MSG rests closed after its calibration): closing from inside the part would end at
    once "without meeting a part". For a device that grips from inside, the same the other way round."""
    width, speed, force, timeout = args
    try:
        now: float | None = device.read_state().width
    except GripperError as exc:  # the grasp itself will report a device that does not answer
        log.debug("%s: no state before the grasp: %s", device.name, exc)
        now = None
    if now is not None:
        inside = device.grips_from_inside
        if inside and now > width:
            to = max(width - GRASP_CLEARANCE, limits.min_width)
            latch.latching(lambda: device.move(to, speed, timeout))
        elif not inside and now < width:
            to = min(width + GRASP_CLEARANCE, limits.max_width)
            latch.latching(lambda: device.move(to, speed, timeout))
        handle = motions.current()
        if handle is not None:
            motions.may_send(handle)  # stopped while opening: do not grasp after all
    return latch.latching(lambda: device.grasp(width, speed, force, timeout))
