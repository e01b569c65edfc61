"""What ``grippers probe`` sends on a raw UART to tell a silent STEPFOC driver from a device that speaks
something else: the line built here, beside the codec, so the CLI builds none of its own."""

from __future__ import annotations

from .uart_protocol import format_command


def identify_request() -> bytes:
    """``#Gripinfo``, which the firmware answers with its identity lines (docs/protocols.md §2 UART)."""
    return format_command("Gripinfo")
