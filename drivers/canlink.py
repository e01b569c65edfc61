"""What a failing CAN interface means to a user, in one place for both families' CAN transports.

python-can's socketcan bus raises ``CanOperationError`` with the socket's errno when the Linux interface
changes under it (measured on a 6.1 kernel with ``vcan``, ``ip link set vcan0 down/up``; python-can 4.6,
``can/interfaces/socketcan/socketcan.py`` keeps the errno in ``error_code``):

* interface set down: a ``recv`` blocked at that moment raises ENETDOWN once (the kernel queues the error on
  every socket bound to the interface, ``net/can/raw.c`` ``raw_notify`` NETDEV_DOWN), later ``recv`` calls
  just time out, and every ``send`` raises ENETDOWN. Once the interface is up again the SAME socket works.
* interface deleted (``ip link delete``, a USB adapter unplugged): ``recv`` raises ENODEV, ``send`` ENXIO,
  and a socket bound to it never works again, even when an interface of that name comes back (it is a new
  interface index): only a fresh bus does.

So a lost link is reported naming the interface and the cause, and a reconnection opens a fresh bus (which
covers both cases).
"""

from __future__ import annotations

import errno
from typing import Any

import can  # every module that imports this one speaks CAN through python-can already

from .virtual_can import WaitableVirtualBus, waitable

__all__ = ["LINK_ERRNOS", "describe_failure", "is_link_failure", "open_bus", "standard_message"]

# errno values that mean "the interface itself is gone or down", not "this one frame failed"
LINK_ERRNOS = frozenset({errno.ENETDOWN, errno.ENODEV, errno.ENXIO, errno.ENETUNREACH})


def _errno(exc: BaseException) -> int | None:
    code = getattr(exc, "error_code", None)  # python-can's CanError
    if not isinstance(code, int):
        code = getattr(exc, "errno", None)  # a plain OSError
    return code if isinstance(code, int) else None


def is_link_failure(exc: BaseException) -> bool:
    """True when ``exc`` says the interface is down or gone (a reconnection can help), not a full queue."""
    return _errno(exc) in LINK_ERRNOS


def describe_failure(exc: BaseException, channel: object, what: str) -> str:
    """One line for a failed ``what`` ("send", "receive") on ``channel``, naming the interface and cause."""
    code = _errno(exc)
    if code == errno.ENETDOWN:
        cause = f"CAN interface {channel} is down (ip link set {channel} up)"
    elif code in (errno.ENODEV, errno.ENXIO):
        cause = f"CAN interface {channel} is gone (deleted or unplugged)"
    else:  # one frame failed (a full queue, a bus-off controller): the device named in the error says where
        return f"{what} failed: {exc}"
    return f"{what} failed: {cause}: {exc}"


def standard_message(arbitration_id: int, data: bytes, remote: bool) -> can.Message:
    """A python-can message of an 11-bit identifier: the only frame format the STEPFOC firmware speaks
    (its client and its simulator build their frames here)."""
    return can.Message(arbitration_id=arbitration_id, data=data, is_extended_id=False, is_remote_frame=remote)


# Interfaces whose python-can module needs a package python-can does not install itself, and the extra that
# brings it: gs_usb (candleLight, CANable in candleLight firmware) imports ``usb`` (pyusb) and ``gs_usb``.
NEEDS_EXTRA = {"gs_usb": ("pyusb and gs-usb", "grippers[usb]")}


def open_bus(**kwargs: Any) -> can.BusABC:
    """``can.Bus(**kwargs)``, with a missing optional package named with the extra that installs it.

    python-can says "Cannot import module can.interfaces.gs_usb for CAN interface 'gs_usb': No module named
    'usb'" (a CanInterfaceNotImplementedError); the user needs to know what to install. The same exception
    type is raised, so callers' handling (a ConnectionLost naming the device) is unchanged.

    ``virtual`` opens python-can's virtual bus with a descriptor an event loop can wait on, where the platform
    has one (:mod:`.virtual_can`): the same channels and frames, so it talks to any other user of them."""
    interface = str(kwargs.get("interface") or "")
    if interface == "virtual" and waitable():
        # python-can's virtual bus, with a descriptor an event loop can wait on (drivers/virtual_can.py)
        return WaitableVirtualBus(**{k: v for k, v in kwargs.items() if k != "interface"})
    try:
        return can.Bus(**kwargs)
    except (can.CanInterfaceNotImplementedError, ImportError) as exc:
        needs = NEEDS_EXTRA.get(interface)
        if needs is None:
            raise
        packages, extra = needs
        text = str(exc)
        raise can.CanInterfaceNotImplementedError(
            f"the {interface} interface needs {packages}: pip install '{extra}' "
            f"(python-can: {' '.join(text.split())})"
        ) from exc
