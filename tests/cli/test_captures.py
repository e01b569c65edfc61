"""The capture readers the monitor decodes: candump logs, hex dumps, raw files."""

from __future__ import annotations

import pytest

from grippers.drivers.captures import (
    FROM_DEVICE,
    TO_DEVICE,
    UNKNOWN_DIRECTION,
    CaptureError,
    parse_candump,
    parse_hex_dump,
    sniff_format,
)


def test_candump_log_format_data_and_remote_frames() -> None:
    lines = [
        "(1436509052.249713) vcan0 044#2A366C2BBA",
        "(1436509052.250000) can0 515#R",
        "# a comment",
        "",
        "(1436509052.260000) can0 1F334455#1122 T",
    ]
    recs = list(parse_candump(lines))
    assert [r.arbitration_id for r in recs] == [0x044, 0x515, 0x1F334455]
    assert recs[0].data == bytes.fromhex("2A366C2BBA") and recs[0].timestamp == pytest.approx(
        1436509052.249713
    )
    assert recs[1].is_remote and recs[1].data == b""
    assert recs[2].is_extended and not recs[0].is_extended
    assert recs[0].channel == "vcan0"


def test_candump_screen_format_with_and_without_timestamp() -> None:
    lines = [
        "  can0  07A   [4]  DE AD BE EF",
        "(1700000000.500000)  can0  TX - -  014   [0]  remote request",
        "  can0  123   [0]  ",
    ]
    recs = list(parse_candump(lines))
    assert recs[0].arbitration_id == 0x7A and recs[0].data == bytes.fromhex("DEADBEEF")
    assert recs[0].timestamp is None
    assert recs[1].is_remote and recs[1].timestamp == 1700000000.5
    assert recs[2].data == b""


@pytest.mark.parametrize(
    "line", ["(1.0) can0 12G#00", "hello world", "(1.0) can0 123#ABC", "  can0  123   [3]  00 11"]
)
def test_candump_bad_lines_name_their_line_number(line: str) -> None:
    with pytest.raises(CaptureError, match="line 2"):
        list(parse_candump(["(1.0) can0 123#00", line]))


def test_hex_dump_plain_xxd_hexdump_and_directions() -> None:
    lines = [
        "AA AA AA 01 00 00 E8 10",
        "> aaaaaa010000e810",
        "< 0xAA, 0xAA, 0xAA, 0x20, 0x02, 0x00, 0x00, 0x00, 0xB3, 0xFD",
        "(12.5) rx AA AA AA 20 02 00 00 00 B3 FD",
        "00000000: aaaa aa01 0000 e810                      ........",
        "00000000  aa aa aa 01 00 00 e8 10                           |........|",
        "host->gripper AA",
    ]
    chunks = list(parse_hex_dump(lines))
    packet = bytes.fromhex("AAAAAA010000E810")
    assert chunks[0].data == packet and chunks[0].direction == UNKNOWN_DIRECTION
    assert chunks[1].direction == TO_DEVICE and chunks[1].data == packet
    assert chunks[2].direction == FROM_DEVICE and chunks[2].data == bytes.fromhex("AAAAAA2002000000B3FD")
    assert chunks[3].timestamp == 12.5 and chunks[3].direction == FROM_DEVICE
    assert chunks[4].data == packet and chunks[5].data == packet
    assert chunks[6].direction == TO_DEVICE and chunks[6].data == b"\xaa"


def test_hex_dump_rejects_non_hex_with_line_number() -> None:
    with pytest.raises(CaptureError, match="line 2"):
        list(parse_hex_dump(["AA", "AZ"]))


def test_sniff_format() -> None:
    assert sniff_format(b"(1.0) can0 123#00\n") == "candump"
    assert sniff_format(b"AA AA AA 01 00 00 E8 10\n") == "hex"
    assert sniff_format(bytes.fromhex("AAAAAA010000E810")) == "raw"
    assert sniff_format(b"hello there\n") == "raw"
