"""Target 1: the WSG packet parser on a stream of mixed replies fed in random chunks.

The stream is what a client reads while a motion runs with auto updates on: status/width/speed/force updates,
E_CMD_PENDING acknowledgements, final replies and an occasional long reply (system information, loop data).
It is cut into chunks of random sizes (seeded), the way TCP hands data to ``recv``, so packets straddle chunk
borders. The baseline is the smallest correct loop one could write: ``struct`` for the header, the CRC
table in a per-byte loop, no resynchronisation, no events.
"""

from __future__ import annotations

import random
import struct

from benchmarks.common import Result, best_rate, rate
from grippers.drivers.wsg.commands import Cmd, GraspingState, SystemFlags, encode_reply
from grippers.drivers.wsg.protocol import CRC_TABLE, Packet, PacketParser, Status, encode_packet

TARGET_PACKETS_PER_S = 100_000


def reply_stream(n_packets: int, seed: int = 6) -> tuple[bytes, int]:
    """``n_packets`` mixed reply packets as one byte string; returns (stream, packet count)."""
    rnd = random.Random(seed)
    width = 110.0
    packets = []
    for i in range(n_packets):
        kind = i % 10
        width = max(0.0, width - rnd.random())
        if kind in (0, 4, 8):
            payload = encode_reply(Cmd.GET_WIDTH, width=width)
            cmd = Cmd.GET_WIDTH
        elif kind == 1:
            payload = encode_reply(Cmd.GET_SPEED, speed=rnd.uniform(0, 420))
            cmd = Cmd.GET_SPEED
        elif kind == 2:
            payload = encode_reply(Cmd.GET_FORCE, force=rnd.uniform(0, 80))
            cmd = Cmd.GET_FORCE
        elif kind == 3:
            payload = encode_reply(Cmd.GET_SYSTEM_STATE, state=SystemFlags(rnd.choice((1, 3, 0x10, 0x1001))))
            cmd = Cmd.GET_SYSTEM_STATE
        elif kind == 5:
            payload = encode_reply(Cmd.GET_GRASPING_STATE, state=GraspingState(rnd.randrange(8)))
            cmd = Cmd.GET_GRASPING_STATE
        elif kind == 6:
            payload = encode_reply(Cmd.PREPOSITION, Status.E_CMD_PENDING)
            cmd = Cmd.PREPOSITION
        elif kind == 7:
            payload = encode_reply(Cmd.PREPOSITION)
            cmd = Cmd.PREPOSITION
        elif i % 20 == 9:
            payload = encode_reply(Cmd.LOOP, data=bytes(rnd.randrange(256) for _ in range(rnd.randrange(64))))
            cmd = Cmd.LOOP
        else:
            payload = encode_reply(Cmd.GET_TEMPERATURE, temperature=rnd.uniform(20, 60))
            cmd = Cmd.GET_TEMPERATURE
        packets.append(encode_packet(cmd, payload))
    return b"".join(packets), n_packets


def random_chunks(stream: bytes, seed: int = 7, max_chunk: int = 128) -> list[bytes]:
    rnd = random.Random(seed)
    chunks = []
    pos = 0
    while pos < len(stream):
        n = rnd.randint(1, max_chunk)
        chunks.append(stream[pos : pos + n])
        pos += n
    return chunks


_HEADER = struct.Struct("<3sBH")


def reference_parse(chunks: list[bytes]) -> int:
    """The minimal loop: append, read the header with struct, checksum with the table, cut. Counts packets."""
    table = CRC_TABLE
    buf = bytearray()
    count = 0
    for chunk in chunks:
        buf += chunk
        while len(buf) >= 6:
            _, command, size = _HEADER.unpack_from(buf)
            end = 8 + size
            if len(buf) < end:
                break
            crc = 0xFFFF
            for byte in buf[:end]:
                crc = table[(crc & 0xFF) ^ byte] ^ (crc >> 8)  # the same update as crc16()
            if crc == 0:
                Packet(command, bytes(buf[6 : end - 2]))
                count += 1
            del buf[:end]
    return count


def parser_parse(chunks: list[bytes]) -> int:
    parser = PacketParser()
    feed = parser.feed
    count = 0
    for chunk in chunks:
        count += len(feed(chunk))
    return count


def run(quick: bool = False) -> list[Result]:
    n = 5_000 if quick else 20_000
    repeats = 3 if quick else 7
    stream, count = reply_stream(n)
    chunks = random_chunks(stream)
    # both must see every packet, else the comparison means nothing
    assert parser_parse(chunks) == count, "parser lost packets"
    assert reference_parse(chunks) == count, "reference lost packets"
    ours = best_rate(lambda: parser_parse(chunks), repeats)
    ref = best_rate(lambda: reference_parse(chunks), repeats)
    avg = len(stream) / count
    return [
        Result(
            "1 wsg parser",
            rate(ours, "pkt"),
            rate(ref, "pkt") + " (ref loop)",
            f"{ours / ref:.2f}x",
            f">= {TARGET_PACKETS_PER_S // 1000} k pkt/s",
            ours >= TARGET_PACKETS_PER_S,
            [
                f"{count} mixed replies, {avg:.1f} bytes average, chunks of 1..128 bytes; "
                f"{ours * avg / 1e6:.1f} MB/s"
            ],
        )
    ]
