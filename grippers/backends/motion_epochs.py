"""The supersede rule's counter lives with the drivers (grippers/drivers/motion_epochs.py): the MSG's driver
device (drivers/stepfoc/device.py) runs it below the API layer. Re-exported here for the backends."""

from grippers.drivers.motion_epochs import MotionEpochs

__all__ = ["MotionEpochs"]
