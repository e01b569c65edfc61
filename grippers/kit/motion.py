"""Waiting for a motion's end by polling, the way every polled device needs it (backend kit, issue 28 §4).

A device that learns the end of a motion only by reading its status (the Robotiq's gOBJ, the ACME R1's
MOVING bit, the MSG's position) writes the same loop each time: read, map a fault to a typed error, check
the end condition, and end early when something newer happened. Written once here, so the rule and its
words are the same on every family:

- :class:`MotionEpochs` numbers the device's motions. Every motion, and every stop, begins a new epoch; a
  wait whose epoch is no longer the current one ends with the cause recorded by whatever began the newer
  one ("superseded by a newer motion", "aborted by stop()"), so an older motion is never reported done when
  the jaws went on to serve a newer one.
- :func:`poll_until` is the loop: it returns the status that satisfied ``done`` and ends, never as
  success, on a newer epoch, on the gripper's close (:meth:`grippers.device.DeviceContext.closed`), on a
  fault the device maps to an error, or at the timeout (``GripperTimeout`` naming the device and the
  command). Every wait has a bound.

A :class:`~grippers.device.Device` uses both: ``motion = epochs.begin(...)`` before it writes the target,
``epochs.begin("aborted by stop()")`` in :meth:`~grippers.device.Device.stop` (and in
:meth:`~grippers.device.Device.supersede` for a device that
:attr:`~grippers.device.Device.moves_to_new_targets`), and ``poll_until(read, done,
context=self.context, command=..., timeout=..., epochs=epochs, motion=motion)`` to wait.
"""

from __future__ import annotations

import time
from collections.abc import Callable
from typing import TYPE_CHECKING, TypeVar

from grippers.drivers.errors import ConnectionLost, GripperError, GripperTimeout
from grippers.drivers.motion_epochs import MotionEpochs

if TYPE_CHECKING:
    from grippers.device import DeviceContext

__all__ = ["POLL_PERIOD", "MotionEpochs", "poll_until"]

S = TypeVar("S")

POLL_PERIOD = 0.005
"""Seconds between two status reads of a wait: an exchange at 115200 baud takes about as long, so a serial
device is polled back to back, and a TCP one is not flooded."""


def poll_until(
    read: Callable[[], S],
    done: Callable[[S], bool],
    *,
    context: DeviceContext,
    command: str,
    timeout: float,
    epochs: MotionEpochs | None = None,
    motion: int = 0,
    fault: Callable[[S], GripperError | None] | None = None,
    period: float = POLL_PERIOD,
) -> S:
    """Read the status with ``read()`` until ``done(status)``, and return that status.

    Ends early, never as success:

    - the gripper was closed (``context.closed()``): ``ConnectionLost``, instead of polling a closed link;
    - ``epochs`` began a newer epoch than ``motion`` (a newer motion, a stop, a fast stop): ``CommandFailed``
      with the cause the newer epoch gave; checked before and after each read, so a status read while the
      stop went out is not taken for this motion's end;
    - ``fault(status)`` returned an error (the device's fault mapped to a typed error, or a motion ended by
      another program): that error is raised;
    - ``timeout`` seconds passed: ``GripperTimeout`` naming the device (``context.name``) and ``command``.

    ``read`` raises what it raises (a lost link, a silent device): the wait ends with it.
    """
    deadline = time.monotonic() + timeout
    while True:
        if context.closed():
            raise ConnectionLost(
                "the gripper was closed during the motion", device=context.name, command=command
            )
        if epochs is not None:
            epochs.check(motion, command=command, device=context.name)
        status = read()
        if epochs is not None:
            epochs.check(motion, command=command, device=context.name)
        if fault is not None:
            error = fault(status)
            if error is not None:
                raise error
        if done(status):
            return status
        if time.monotonic() >= deadline:
            raise GripperTimeout(f"not done after {timeout:g} s", device=context.name, command=command)
        time.sleep(period)
