"""The supersede rule's counter lives with the drivers (grippers/drivers/motion_epochs.py): the MSG's driver
device (drivers/stepfoc/device.py) runs it below the API layer; plugins take it from :mod:`grippers.kit`.
Re-exported here for the backends that import it from this place."""

from grippers.drivers.motion_epochs import MotionEpochs

__all__ = ["MotionEpochs"]
