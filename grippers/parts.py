"""What each mixin of :class:`~grippers.gripper.Gripper` takes from the core class, declared once.

The gripper is put together from small mixins (limit checks, servo, optional features, connection hooks),
each in its own module; every one of them names the device in its errors and refuses work on a closed
gripper, through these two members that the core class provides.
"""

from __future__ import annotations

from abc import abstractmethod


class GripperPart:
    """The core members every part of a gripper uses (provided by grippers/gripper.py)."""

    @property
    @abstractmethod
    def name(self) -> str:
        """``PROFILE@URL``: how errors and logs name this gripper."""

    @abstractmethod
    def _check_open(self, command: str) -> None:
        """Raise if the gripper is closed (or its link is down, with reconnect=true)."""
