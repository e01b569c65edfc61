"""Weiss/SCHUNK WSG grippers: sans-IO codec (protocol, commands, session), transports and the threaded client.

The sans-IO core (``protocol``, ``commands``, ``session``) does no I/O; ``client`` adds threads and sockets
on top, over the byte lines of ``transports``. The client and the simulator (``sim``) share ``protocol``.
The client's names load lazily, so importing the codec pulls in no socket, thread, serial or CAN module.
"""

from .commands import (
    COMMANDS,
    Cmd,
    CommandSpec,
    DeviceType,
    FingerFlags,
    FingerInfo,
    FingerType,
    FirmwareVersion,
    GraspingState,
    GraspingStatistics,
    Reply,
    SoftLimits,
    SystemFlags,
    SystemInfo,
    SystemLimits,
    decode_reply,
    decode_request,
    describe,
    encode_reply,
    encode_request,
)
from .protocol import (
    PREAMBLE,
    BadLength,
    ChecksumError,
    Discarded,
    Packet,
    PacketParser,
    Status,
    can_frames,
    crc16,
    encode_packet,
)

_LAZY = {"Pending", "Subscription", "WsgClient"}


def __getattr__(name: str) -> object:
    if name in _LAZY:
        from . import client

        return getattr(client, name)
    raise AttributeError(f"module 'grippers.drivers.wsg' has no attribute {name!r}")


__all__ = [
    "COMMANDS",
    "PREAMBLE",
    "BadLength",
    "ChecksumError",
    "Cmd",
    "CommandSpec",
    "DeviceType",
    "Discarded",
    "FingerFlags",
    "FingerInfo",
    "FingerType",
    "FirmwareVersion",
    "GraspingState",
    "GraspingStatistics",
    "Packet",
    "PacketParser",
    "Pending",
    "Reply",
    "SoftLimits",
    "Status",
    "Subscription",
    "SystemFlags",
    "SystemInfo",
    "SystemLimits",
    "WsgClient",
    "can_frames",
    "crc16",
    "decode_reply",
    "decode_request",
    "describe",
    "encode_packet",
    "encode_reply",
    "encode_request",
]
