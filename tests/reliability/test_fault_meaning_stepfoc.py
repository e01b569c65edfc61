"""Each fault hook means the same on every simulator and transport (issue 23 §3): one rule,
drivers/simkit.apply_fault, used by the WSG engine and the MSG CAN and UART servers. Checked on the wire with
raw frames and raw lines (no client code)."""

from __future__ import annotations

import os
import select
import time
import uuid

import can
import pytest

from grippers.drivers.simkit import Fault, FaultKind, apply_fault, first_half, flip_last_byte
from grippers.drivers.stepfoc.sim import MsgModel, serve_can, serve_uart

NODE = 14  # no other test uses it on a shared bus
POLL_ID = NODE << 7 | 61 << 1
STATUS_ID = NODE << 7 | 60 << 1


def test_apply_fault_is_one_rule_for_every_kind() -> None:
    reply = b"\x01\x02\x03\x04"

    def run(kind: FaultKind, seconds: float = 0.0) -> tuple[list[bytes], float]:
        return apply_fault(
            reply,
            Fault(kind, seconds),
            corrupt=flip_last_byte,
            truncate=first_half,
            error_bit=lambda r: r + b"!",
        )

    assert apply_fault(reply, None, corrupt=flip_last_byte, truncate=first_half) == ([reply], 0.0)
    assert run(FaultKind.DROP) == ([], 0.0)
    assert run(FaultKind.DELAY, 0.3) == ([reply], 0.3)
    assert run(FaultKind.CORRUPT) == ([b"\x01\x02\x03\xfb"], 0.0)
    assert run(FaultKind.TRUNCATE) == ([b"\x01\x02"], 0.0)
    assert run(FaultKind.DUPLICATE) == ([reply, reply], 0.0)
    assert run(FaultKind.ERROR_BIT) == ([reply + b"!"], 0.0)
    no_bit = apply_fault(reply, Fault(FaultKind.ERROR_BIT), corrupt=flip_last_byte, truncate=first_half)
    assert no_bit == ([reply], 0.0)  # a protocol without an error bit sends it unchanged


def can_replies(inject: str, *args: float) -> list[can.Message]:
    channel = f"faults-{uuid.uuid4().hex[:8]}"
    with (
        serve_can(
            [MsgModel(node=NODE, current_noise=False)], f"can://virtual/{channel}", time_scale=10.0
        ) as srv,
        can.Bus(interface="virtual", channel=channel) as bus,
    ):
        getattr(srv.faults, inject)(*args)
        bus.send(can.Message(arbitration_id=POLL_ID, data=b"", is_extended_id=False))
        out = []
        deadline = time.monotonic() + 0.6
        while time.monotonic() < deadline:
            msg = bus.recv(timeout=0.05)
            if msg is not None and msg.arbitration_id >> 1 == STATUS_ID >> 1:
                out.append(msg)
        return out


def uart_answers(inject: str, *args: float) -> bytes:
    with serve_uart(MsgModel(), "pty", time_scale=10.0) as srv:
        fd = os.open(srv.path, os.O_RDWR | os.O_NOCTTY)
        try:
            getattr(srv.faults, inject)(*args)
            os.write(fd, b"#Gripper\n")
            data = b""
            deadline = time.monotonic() + 0.6
            while time.monotonic() < deadline:
                ready, _, _ = select.select([fd], [], [], 0.05)
                if ready:
                    data += os.read(fd, 4096)
            return data
        finally:
            os.close(fd)


LINE = b"Gripper: 1\r\n"


@pytest.mark.parametrize(
    ("inject", "args", "frames", "lines"),
    [
        ("duplicate_replies", (1,), 2, LINE + LINE),
        ("drop_replies", (1,), 0, b""),
        ("delay_replies", (0.2, 1), 1, LINE),
        ("truncate_replies", (1,), 1, LINE[: len(LINE) // 2]),
        ("error_bit_replies", (1,), 1, LINE),
    ],
)
def test_each_fault_means_the_same_on_can_and_uart(
    inject: str, args: tuple, frames: int, lines: bytes
) -> None:
    replies = can_replies(inject, *args)
    assert len(replies) == frames
    if inject == "truncate_replies":
        assert len(replies[0].data) == 2  # half of the 4-byte 60 frame
    if inject == "error_bit_replies":
        assert replies[0].arbitration_id & 1
    assert uart_answers(inject, *args) == lines
