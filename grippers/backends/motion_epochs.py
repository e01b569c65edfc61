"""Moved to :mod:`grippers.kit.motion` (the backend kit, public); re-exported here for the backends that
still import it from this place."""

from __future__ import annotations

from grippers.kit.motion import MotionEpochs

__all__ = ["MotionEpochs"]
