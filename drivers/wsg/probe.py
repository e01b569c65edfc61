"""What ``grippers probe`` sends on a raw connection to tell a silent WSG from a device that speaks something
else (wrong protocol or baud rate), and how it reads the answer: packets built here, beside the codec, so the
CLI builds none of its own."""

from __future__ import annotations

from .commands import Cmd
from .protocol import Packet, PacketParser, encode_packet


def identify_request() -> bytes:
    """GET_SYSTEM_INFO (50h), which every WSG firmware answers (WSG manual 4.0.x §3.5.1)."""
    return encode_packet(Cmd.GET_SYSTEM_INFO)


def goodbye(transport: str) -> bytes:
    """What to send before closing: on TCP a WSG whose connection closes without DISCONNECT (07h) enters FAST
    STOP (docs/protocols.md §1 "Field details"), so a slow but real gripper must not be left in it."""
    return encode_packet(Cmd.DISCONNECT) if transport == "tcp" else b""


def holds_a_packet(data: bytes) -> bool:
    """Whether ``data`` holds one whole WSG packet (a real WSG that answered late, not garbage)."""
    return any(isinstance(item, Packet) for item in PacketParser().feed(data))
