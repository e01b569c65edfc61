"""Target 5: sixteen simulated MSG nodes on one python-can bus, each polled in a closed loop.

One client thread per node sends an empty 61 (poll) and waits for its 60 before the next, all sixteen at once
through one :class:`StepfocBus` (one reader thread). The simulator shares the process (python-can's
``virtual`` bus is in-process), so the client's CPU time is read from the CPU clocks of the client's own
threads (the sixteen pollers and the bus reader), never from the process total.

The bus limit is computed, not measured: a classic CAN data frame with an 11-bit identifier has 34 + 8n bits
from SOF to the end of the CRC, which bit stuffing can stretch by one bit in four after the first, plus 10
bits of delimiters, ACK and EOF and 3 of interframe space (ISO 11898-1). At 1 Mbit/s a poll (0 data bytes)
and its status (4 bytes) take the sum of both frames.
"""

from __future__ import annotations

import threading
import time
import uuid

import can

from benchmarks.common import Result, thread_cpu_clock, us
from grippers.drivers.stepfoc.can_client import StepfocBus
from grippers.drivers.stepfoc.can_protocol import Cmd, pack_id
from grippers.drivers.stepfoc.sim import MsgModel, serve_can

BITRATE = 1_000_000
NODES = 16
CPU_SHARE_LIMIT = 0.25


def frame_bits(data_bytes: int) -> int:
    """Worst-case bits on the wire of a classic base-format data frame, interframe space included."""
    stuffable = 34 + 8 * data_bytes  # SOF, 11-bit id, RTR, IDE, r0, DLC, data, 15-bit CRC
    stuff = (stuffable - 1) // 4  # worst case: a stuff bit after every 4 bits following the first 5
    return stuffable + stuff + 10 + 3  # CRC delimiter, ACK slot + delimiter, 7-bit EOF; 3-bit IFS


POLL_BITS = frame_bits(0) + frame_bits(4)  # empty 61, then the 4-byte 60


def raw_loop_cpu(channel: str, node: int, seconds: float) -> float:
    """CPU per round trip of the barest python-can loop (send a poll, recv until its 60) on the same bus.

    This is what the transport itself costs the sending thread (on the virtual bus: a Message copy per
    receiver and a queue hand-over), which SocketCAN would replace by two system calls.
    """
    bus = can.Bus(interface="virtual", channel=channel)
    poll = can.Message(arbitration_id=pack_id(node, Cmd.GRIPPER_COMMAND), data=b"", is_extended_id=False)
    reply_id = pack_id(node, Cmd.GRIPPER_STATUS)
    n = 0
    try:
        c0, end = time.thread_time(), time.perf_counter() + seconds
        while time.perf_counter() < end:
            bus.send(poll)
            while True:
                msg = bus.recv(1.0)
                if msg is None:
                    raise TimeoutError("the simulator did not answer a poll")
                if msg.arbitration_id == reply_id:
                    break
            n += 1
        return (time.thread_time() - c0) / n
    finally:
        bus.shutdown()


def _polling_slice(bus: StepfocBus, seconds: float) -> tuple[float, int, float]:
    """Sixteen pollers for ``seconds``: (client CPU per round trip, round trips, wall time)."""
    counts = [0] * NODES
    cpu = [0.0] * NODES
    start = threading.Barrier(NODES + 1)
    stop = threading.Event()

    def poller(i: int) -> None:
        node = bus.node(i, timeout=1.0)
        node.poll()  # warm up
        start.wait()
        c0 = time.thread_time()
        n = 0
        while not stop.is_set():
            node.poll()
            n += 1
        cpu[i] = time.thread_time() - c0
        counts[i] = n

    threads = [threading.Thread(target=poller, args=(i,), daemon=True) for i in range(NODES)]
    for t in threads:
        t.start()
    reader = bus._reader.thread  # the bus's reader thread
    assert reader is not None and reader.ident is not None
    reader_cpu = thread_cpu_clock(reader.ident)
    start.wait()
    r0, w0 = reader_cpu(), time.perf_counter()
    time.sleep(seconds)
    stop.set()
    for t in threads:
        t.join(5)
    wall = time.perf_counter() - w0
    total = sum(counts)
    return (sum(cpu) + reader_cpu() - r0) / total, total, wall


def run(quick: bool = False) -> list[Result]:
    # Slices of polling alternate with slices of the bare loop, and each side keeps its least disturbed
    # slice (the fastest run, as in targets 1 and 4): sixteen threads' CPU on a shared 2-core machine
    # varies by half from one run to the next with the rest of the machine's load.
    slices, seconds = (3, 1.0) if quick else (5, 2.0)
    channel = f"bench-{uuid.uuid4().hex[:8]}"
    models = [MsgModel(node=n) for n in range(NODES)]
    server = serve_can(models, f"can://virtual/{channel}")
    bus = StepfocBus(interface="virtual", channel=channel)
    client_cpu: list[float] = []
    raw_cpu: list[float] = []
    total = 0
    wall = 0.0
    try:
        for _ in range(slices):
            per_rt, n, w = _polling_slice(bus, seconds)
            client_cpu.append(per_rt)
            total += n
            wall += w
            raw_cpu.append(raw_loop_cpu(channel, 0, seconds / 3))
    finally:
        bus.close()
        server.close()
    rate = total / wall
    cpu_per_rt, raw = min(client_cpu), min(raw_cpu)
    bus_per_rt = POLL_BITS / BITRATE
    limit = BITRATE / POLL_BITS
    own = cpu_per_rt - raw
    share = own / bus_per_rt
    return [
        Result(
            "5 stepfoc bus, 16 nodes",
            f"own CPU {us(own)}/rt",
            f"bus {us(bus_per_rt)}/rt",
            f"{share:.2f}",
            f"CPU < {CPU_SHARE_LIMIT:g} x bus",
            share < CPU_SHARE_LIMIT,
            [
                f"{rate:.0f} round trips/s aggregate ({total} in {wall:.1f} s, python-can virtual bus, "
                f"simulator in-process); 1 Mbit/s limit for these frames: {limit:.0f}/s "
                f"({frame_bits(0)} + {frame_bits(4)} bits worst case)",
                f"client threads' CPU {us(cpu_per_rt)}/rt (pollers and bus reader; best of {slices} slices, "
                f"{us(max(client_cpu))} the worst) minus {us(raw)}/rt that a bare python-can send/recv loop "
                f"spends on the virtual bus (best of {slices}) = own CPU",
            ],
        )
    ]
