"""A gripper nobody references any more is closed, with a ResourceWarning, as sockets and files are.

Why (issue 39 §3): re-running ``g = grippers.open('sim://wsg50')`` in a notebook cell six times left the
threads and transports of five unreachable grippers behind (2 threads per threaded gripper, 8 per asyncio
one), and a serial port or a WSG's single TCP connection with them, until the kernel restarted. The standard
library's answer for a resource its owner forgot is the finalizer: close it and say so with a
:class:`ResourceWarning` (shown with ``python -X dev`` or ``-W default``, and by pytest).

Why on a thread of its own: the cyclic garbage collector runs in whichever thread happens to allocate,
possibly a driver's reader holding the very lock that closing the transport takes; closing there could
deadlock, and ``close()`` joins the reader. The finalizer only starts the close elsewhere and returns.
"""

from __future__ import annotations

import logging
import sys
import threading
import warnings
from collections.abc import Callable
from typing import Any

log = logging.getLogger(__name__)


def close_unreferenced(owner: Any, what: str, close: Callable[[], object]) -> None:
    """From ``owner.__del__``: unless ``owner`` is closed (or its ``__init__`` failed before it set
    ``_closed``), run ``close`` on a short-lived thread, then warn ``unclosed WHAT NAME``.
    Never raises (a finalizer's exception is only printed); at interpreter exit, when no thread can start any
    more, it does nothing: the process ending releases everything anyway."""
    if owner.__dict__.get("_closed", True) or sys.is_finalizing():
        return  # at interpreter exit a new thread never starts (Thread.start() waits for ever on 3.11)
    name = f"{what} {owner.name}"

    def run() -> None:
        try:
            close()
        except Exception:  # noqa: BLE001 - nobody to hand it to: logged
            log.exception("closing the unreferenced %s failed", name)

    try:
        threading.Thread(target=run, name=f"grippers-unclosed {name}", daemon=True).start()
    except RuntimeError:  # interpreter shutdown
        return
    try:
        warnings.warn(f"unclosed {name}: close it, or open it in a with block", ResourceWarning, 2, owner)
    except Exception:  # noqa: BLE001 - warnings turned into errors: the close runs anyway
        pass
