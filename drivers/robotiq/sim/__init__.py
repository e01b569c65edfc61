"""The simulated Robotiq gripper: the register model (pure, simulated time) and its pty/TCP servers."""

from .model import ModelParams, RobotiqModel
from .server import RobotiqSimServer, serve

__all__ = ["ModelParams", "RobotiqModel", "RobotiqSimServer", "serve"]
