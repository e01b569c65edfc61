"""A simulated WSG gripper: the pure device model and its servers over TCP, UDP, a pty and python-can."""

from drivers.wsg.sim.engine import SimServer
from drivers.wsg.sim.model import NOT_MODELLED, SIM_CHOICES, WsgModel
from drivers.wsg.sim.server import serve

__all__ = ["NOT_MODELLED", "SIM_CHOICES", "SimServer", "WsgModel", "serve"]
