"""How a gripper's width maps onto the joints a URDF gives it (the ``joint_names`` parameter).

- One name: a width joint, position = the opening (m). The default, and what a URDF with one prismatic
  joint for the whole opening (or a MoveIt GripperCommand handle with ``command_joint``) expects.
- Two names: two prismatic fingers, each at half the opening (the convention of the WSG's and Franka's URDFs,
  the second usually a mimic joint). MoveIt's GripperCommand handle with ``parallel: true`` sends the sum of
  the two as the position, so a GripperCommand position stays the width; its ParallelGripperCommand handle
  sends one position per configured joint, so a ParallelGripperCommand names one of the two and gives that
  finger's position: half the width.

Velocities follow the positions (a finger moves at half the opening's rate); an effort is the grip force,
which each finger applies whole (action and reaction), so it is not halved.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass


def _valid(name: object) -> bool:
    return (
        isinstance(name, str)
        and bool(name)
        and not name[0].isdigit()
        and name.isascii()
        and all(c.isalnum() or c in "_/" for c in name)
    )


@dataclass(frozen=True)
class JointLayout:
    names: tuple[str, ...]

    @classmethod
    def of(cls, names: Sequence[str]) -> JointLayout:
        names = tuple(names)
        if len(names) not in (1, 2):
            raise ValueError(
                f"joint_names needs one name (the width) or two (the fingers), got {list(names)}"
            )
        bad = [n for n in names if not _valid(n)]
        if bad:
            raise ValueError(f"joint_names: {bad} are not joint names")
        if len(set(names)) != len(names):
            raise ValueError(f"joint_names: {list(names)} names a joint twice")
        return cls(names)

    @property
    def share(self) -> float:
        """The part of the opening each joint's position is."""
        return 1.0 / len(self.names)

    def positions(self, width: float) -> list[float]:
        return [float(width) * self.share] * len(self.names)

    def velocities(self, speed: float) -> list[float]:
        return [float(speed) * self.share] * len(self.names)

    def efforts(self, force: float) -> list[float]:
        return [float(force)] * len(self.names)

    def width_of(self, names: Sequence[str], position: float) -> float:
        """The opening a ParallelGripperCommand asks for: ``position`` of the one joint it names (no name:
        the first configured joint). ValueError for a joint that is not ours."""
        if len(names) > 1:
            raise ValueError(f"one joint expected, got {list(names)}")
        name = names[0] if names else self.names[0]
        if name not in self.names:
            raise ValueError(f"joint {name!r} is not one of {list(self.names)}")
        return float(position) / self.share

    def speed_of(self, velocity: float) -> float:
        return float(velocity) / self.share
