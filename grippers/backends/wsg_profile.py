"""The WSG family's profile model: its transport defaults, device section and simulator settings
(docs/profiles.md), declared by the backend as its ``profile_model``."""

from __future__ import annotations

from typing import Annotated, Literal

from pydantic import Field

from ..profiles import (
    Baudrate,
    CanId,
    Length,
    Port,
    ProfileBase,
    Timeout,
    TimeScale,
    _key,
    _Model,
    list_profiles,
)


class WsgTransport(_Model):
    # Defaults from docs/protocols.md §1 "Transport defaults" (public drivers and set-up notes, not manuals).
    timeout_s: Timeout = 1.0
    tcp_port: Port = 1000
    udp_port: Port = 1500
    udp_local_port: Annotated[int, Field(ge=0, le=65535)] = 1501
    baudrate: Baudrate = 115200
    bytesize: Literal[5, 6, 7, 8] = 8
    parity: Literal["N", "E", "O", "M", "S"] = "N"
    # 1, 1.5 or 2 (one public driver uses 2); 1.5 spelled as a range, since a typing Literal takes no floats.
    stopbits: Literal[1, 2] | Annotated[float, Field(ge=1.5, le=1.5)] = 1
    can_interface: str = "socketcan"
    can_channel: str = "can0"
    can_bitrate: Annotated[int, Field(gt=0)] = 500_000
    can_send_id: CanId = 0x000  # host -> gripper
    can_recv_id: CanId = 0x001  # gripper -> host
    verify_checksum: bool = True


class WsgDevice(_Model):
    device_type: Annotated[int, Field(ge=0, le=255)]  # 50h TYPE: 1 WSG 50, 2 WSG 32, 5 WSG 25, 6 WSG 70
    # Set in the web interface: how far Grip Part (25h) may close past the width (docs/protocols.md §1).
    clamping_travel_mm: Length = 10.0


class WsgSimulator(_Model):
    firmware: Annotated[str, Field(pattern=r"^\d+\.\d+\.\d+$")] = "4.0.1"
    serial: Annotated[int, Field(ge=0, le=0xFFFFFFFF)] = 12345
    part_width_mm: Length | None = None
    force_fingers: bool = False
    time_scale: TimeScale = 1.0


class WsgProfile(ProfileBase):
    family: Literal["wsg"] = "wsg"
    transport: WsgTransport = WsgTransport()
    wsg: WsgDevice
    simulator: WsgSimulator = WsgSimulator()


def wsg_profile_for_device_type(device_type: int) -> WsgProfile | None:
    """The first profile on the search path for the WSG model that reports ``device_type`` in 50h.

    A profile that ``extends`` another is a variant (``wsg50-glass``: the stock WSG 50 limited to 15 N),
    never chosen here: dropped on the search path, it would silently become the profile of every plain
    ``wsg+tcp://`` open and every probe (issue 22 §1). Variants are selected only by name: ``profile=``, or
    opening the profile itself (which connects to its ``url``). A user's file that takes a built-in's NAME
    still replaces that built-in (with or without ``extends`` of it): that is how a user corrects a stock
    profile on purpose.
    """
    for profile in list_profiles():
        variant = profile.extends is not None and _key(profile.extends) != _key(profile.name)
        if isinstance(profile, WsgProfile) and not variant and profile.wsg.device_type == device_type:
            return profile
    return None
