"""A simulated WSG gripper: the pure device model and its servers over TCP, UDP, a pty and python-can."""

from .engine import SimServer
from .model import NOT_MODELLED, SIM_CHOICES, WsgModel
from .server import serve

__all__ = ["NOT_MODELLED", "SIM_CHOICES", "SimServer", "WsgModel", "serve"]
