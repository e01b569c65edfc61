"""Opening a serial port, the one way every family does it: exclusively, and "busy" said as such.

Two processes on one RS-485 or UART line each steal the other's replies, and both then time out with
nothing to say why (issue 43 §5). pyserial's ``exclusive=True`` takes an advisory ``flock`` on the device
(POSIX), so a second process of this library is refused at open; the refusal names the port and, where
``/proc`` tells, the process that holds it. Programs that do not lock (a terminal program, a vendor tool)
are not seen by the lock: the timeout then stands. Every family's serial transport opens its port here
(drivers/links.py, the WSG's and the STEPFOC UART's transports), so the rule lives in one place.
"""

from __future__ import annotations

import errno
import os
from pathlib import Path
from typing import Any

from .errors import ConnectionLost
from .urls import scheme_of

__all__ = ["open_serial_port", "port_holders"]

MAX_HOLDERS_SHOWN = 3
# pyserial's URL handlers that open no device file of their own (nothing to hold exclusively).
_SHARED_URLS = ("loop", "socket", "rfc2217", "spy", "alt", "hwgrep")
_BUSY_ERRNOS = {errno.EAGAIN, errno.EWOULDBLOCK, errno.EBUSY}


def open_serial_port(port: str, *, device: str, **options: Any) -> Any:
    """``serial.serial_for_url(port, exclusive=True, **options)``; :class:`ConnectionLost` naming ``device``
    when the port cannot be opened, "busy" with its holder when another process holds it."""
    import serial  # the kit is importable without a serial port in sight

    exclusive = scheme_of(port) not in _SHARED_URLS
    try:
        return serial.serial_for_url(port, exclusive=True if exclusive else None, **options)
    except (*_open_errors(), serial.SerialException) as exc:
        raise ConnectionLost(open_failure(port, exc), device=device, command="open") from exc


def _open_errors() -> tuple[type[BaseException], ...]:
    """What an open raises besides pyserial's own: OSError, ValueError (a bad port URL), and on POSIX
    termios.error (a tty that vanished while it was being set up)."""
    try:
        import termios
    except ImportError:  # pragma: no cover - Windows
        return (OSError, ValueError)
    return (OSError, ValueError, termios.error)


def open_failure(port: str, exc: BaseException) -> str:
    """What a failed open says: "busy" and the holder for a port another process locked, else the cause."""
    text = str(exc)
    busy = getattr(exc, "errno", None) in _BUSY_ERRNOS or "exclusively lock" in text or "busy" in text.lower()
    if not busy:
        return f"cannot open {port}: {text}"
    holders = port_holders(port)
    held = f"held by {', '.join(holders)}" if holders else "held by another process"
    return f"{port} is busy ({held}): close the other program, or share the gripper with `grippers serve`"


def port_holders(port: str) -> list[str]:
    """``"PID 1234 (grippers monitor ...)"`` for each process with ``port`` open (this one too: a second open
    in one program), as far as ``/proc`` shows (empty without /proc, or for another user's processes)."""
    try:
        target = os.path.realpath(port)
        wanted = os.stat(target).st_rdev
    except OSError:
        return []
    found: list[str] = []
    proc = Path("/proc")
    if not proc.is_dir():
        return []
    for entry in proc.iterdir():
        if not entry.name.isdigit():
            continue
        try:
            fds = list((entry / "fd").iterdir())
        except OSError:
            continue
        for fd in fds:
            try:
                if os.path.realpath(fd) != target or os.stat(fd).st_rdev != wanted:
                    continue
                cmd = (entry / "cmdline").read_bytes().replace(b"\0", b" ").decode(errors="replace").strip()
            except OSError:
                continue
            mine = " : this process" if int(entry.name) == os.getpid() else ""
            found.append(f"PID {entry.name} ({cmd[:60] or '?'}{mine})")
            break
        if len(found) >= MAX_HOLDERS_SHOWN:
            break
    return found
