"""Source Robotics MSG grippers on STEPFOC / Spectral Micro BLDC drivers.

Two ways in: CAN (:mod:`.can_protocol`, sans-IO; :mod:`.can_client`, python-can) and the UART text protocol
(:mod:`.uart_protocol`, :mod:`.uart_client`); :class:`~.device.StepfocDevice` is one gripper over either, with
the one motion-end rule (:mod:`.motion`). :mod:`.sim` holds the device model both simulators share.
docs/protocols.md §2 overrides the MSG document on byte order, bit order and the object-detection bits.
"""

from .can_client import StepfocBus, StepfocNode, open_node
from .can_protocol import (
    COMMANDS,
    Cmd,
    Detection,
    DeviceInfo,
    EncoderData,
    ErrorState,
    FrameLengthError,
    GripperCommand,
    GripperStatus,
    Watchdog,
    WatchdogAction,
    decode_command,
    decode_frame,
    decode_status,
    describe,
    encode_command,
    encode_frame,
    encode_status,
    pack_id,
    unpack_id,
)
from .device import CanLink, StepfocDevice, UartLink

__all__ = [
    "COMMANDS",
    "CanLink",
    "Cmd",
    "Detection",
    "DeviceInfo",
    "EncoderData",
    "ErrorState",
    "FrameLengthError",
    "GripperCommand",
    "GripperStatus",
    "StepfocBus",
    "StepfocDevice",
    "StepfocNode",
    "UartLink",
    "Watchdog",
    "WatchdogAction",
    "decode_command",
    "decode_frame",
    "decode_status",
    "describe",
    "encode_command",
    "encode_frame",
    "encode_status",
    "open_node",
    "pack_id",
    "unpack_id",
]
