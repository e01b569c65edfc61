"""Simulated MSG grippers: one pure device model (:class:`MsgModel`) served over CAN or a UART pty.

``serve(model, listen)`` picks the transport from ``listen``: ``can://INTERFACE/CHANNEL[?node=N]`` or ``pty``.
The UART server is imported lazily so the CAN side works without it (and vice versa).
"""

from __future__ import annotations

from typing import Any

from ...urls import scheme_of
from .can_server import CanSimServer, serve_can
from .model import MsgModel

__all__ = ["CanSimServer", "MsgModel", "serve", "serve_can", "serve_uart"]


def serve_uart(
    model: MsgModel | None = None, listen: str = "pty", *, time_scale: float = 1.0, **kw: Any
) -> Any:
    """Serve ``model`` on a pseudo-terminal (see :mod:`grippers.drivers.stepfoc.sim.uart_server`)."""
    from .uart_server import serve_uart as _serve_uart

    return _serve_uart(model if model is not None else MsgModel(), listen, time_scale=time_scale, **kw)


def serve(models: Any = None, listen: str = "pty", *, time_scale: float = 1.0, **kw: Any) -> Any:
    """Start a simulator on the transport ``listen`` names (``can://…`` or ``pty``)."""
    if scheme_of(listen) in ("can", "stepfoc+can"):
        return serve_can(models, listen, time_scale=time_scale, **kw)
    if listen == "pty" or listen.startswith(("pty", "serial")):
        if isinstance(models, list | tuple):
            if len(models) != 1:
                raise ValueError("a UART serves exactly one gripper")
            models = models[0]
        return serve_uart(models, listen, time_scale=time_scale, **kw)
    raise ValueError(f"unknown listen address {listen!r}: expected can://INTERFACE/CHANNEL or pty")
