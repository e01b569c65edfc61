"""grippers: one interface for robot grippers from different vendors.

    import grippers
    with grippers.open("sim://wsg50") as g:
        g.home()
        result = g.grasp(0.040, force=20)

The heavy parts (pydantic, python-can, the drivers) load on first use, so ``import grippers`` and the
command line start fast.
"""

from __future__ import annotations

import importlib
from typing import TYPE_CHECKING, Any

from ._version import __version__
from .errors import (
    AccessDenied,
    CommandFailed,
    ConnectionLost,
    GripperError,
    GripperTimeout,
    GripperWarning,
    LimitError,
    MotionBlocked,
    NotReferenced,
    NotSupported,
    ProfileAssumed,
    ProfileError,
    ProtocolError,
    ServerBusy,
    URLError,
)

if TYPE_CHECKING:
    from .api import open
    from .gripper import (
        Capability,
        DeviceInfo,
        FastStopActive,
        GraspResult,
        GraspState,
        Gripper,
        GripperState,
        MotionResult,
        StateStream,
    )
    from .motions import MotionHandle
    from .profiles import Limits, Profile, load_profile
    from .recorder import Recorder, record
    from .recording import RecordingError

_LAZY = {
    "open": ".api",
    "Capability": ".gripper",
    "DeviceInfo": ".gripper",
    "FastStopActive": ".gripper",
    "GraspResult": ".gripper",
    "GraspState": ".gripper",
    "Gripper": ".gripper",
    "GripperState": ".gripper",
    "MotionHandle": ".motions",
    "MotionResult": ".gripper",
    "StateStream": ".gripper",
    "Limits": ".profiles",
    "Profile": ".profiles",
    "load_profile": ".profiles",
    # Added to grippers/errors.py by the remote (Zenoh) layer: a peer refused by the server's access rules.
    "AccessDenied": ".errors",
    **{"record": ".recorder", "Recorder": ".recorder", "RecordingError": ".recording"},  # issue 31 §3
}

__all__ = [
    "__version__",
    "AccessDenied",
    "CommandFailed",
    "ConnectionLost",
    "GripperError",
    "GripperTimeout",
    "GripperWarning",
    "LimitError",
    "MotionBlocked",
    "NotReferenced",
    "NotSupported",
    "ProfileAssumed",
    "ProfileError",
    "ProtocolError",
    "ServerBusy",
    "URLError",
    "open",
    "Capability",
    "DeviceInfo",
    "FastStopActive",
    "GraspResult",
    "GraspState",
    "Gripper",
    "GripperState",
    "MotionHandle",
    "MotionResult",
    "StateStream",
    "Limits",
    "Profile",
    "load_profile",
    "record",
    "Recorder",
    "RecordingError",
]


def __getattr__(name: str) -> Any:
    module = _LAZY.get(name)
    if module is None:
        raise AttributeError(f"module 'grippers' has no attribute {name!r}")
    value = getattr(importlib.import_module(module, __name__), name)
    globals()[name] = value
    return value


def __dir__() -> list[str]:
    """``dir(grippers)`` and tab completion list the lazily loaded names too (issue 22 §2)."""
    return sorted(set(globals()) | set(__all__))
