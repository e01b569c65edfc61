"""Issue 12 §4 and issue 16 §4: the monitor survives any frame (extended, FD, error, remote, ids above
0x7FF), shows relative times (-t r as candump) and writes live traffic as a capture that reads back."""

from __future__ import annotations

import threading
import time
from pathlib import Path

import can
from can.interfaces import virtual

from grippers.cli import main
from grippers.drivers.captures import format_candump, format_hex_line, parse_candump, parse_hex_dump

ODD_FRAMES = "\n".join(
    [
        "(100.000000) can0 12345678#DEADBEEF",  # extended id
        "(100.100000) can0 20000004#0000000000000000",  # error frame (CAN_ERR_FLAG | CAN_ERR_CRTL)
        "(100.200000) can0 0F3##1" + "00" * 12,  # CAN FD, 12 bytes
        "(100.300000) can0 07D#R",  # remote frame on a STEPFOC id
        "(100.400000) can0 000#",  # node 0 e-stop
    ]
)


def test_capture_with_odd_frames_decodes_every_line(tmp_path: Path, cli) -> None:
    capture = tmp_path / "odd.log"
    capture.write_text(ODD_FRAMES + "\n")
    r = cli("monitor", str(capture), "--json")
    assert r.returncode == 0, r.stderr
    records = r.json_lines()
    assert [rec["status"] for rec in records[:3]] == ["extended frame", "error frame", "fd frame"]
    assert records[0]["id"] == "12345678" and records[2]["fields"]["bytes"] == 12
    assert len(records) == 5 and records[4]["protocol"] == "stepfoc"


def test_relative_timestamps(tmp_path: Path, cli) -> None:
    capture = tmp_path / "odd.log"
    capture.write_text(ODD_FRAMES + "\n")
    r = cli("monitor", str(capture), "-t", "r")
    stamps = [float(line.split()[0]) for line in r.stdout.splitlines()]
    assert stamps == [0.0, 0.1, 0.2, 0.3, 0.4]
    d = cli("monitor", str(capture), "-t", "d")
    assert [float(line.split()[0]) for line in d.stdout.splitlines()][1:] == [0.1] * 4


def test_live_bus_with_odd_frames_and_write_reads_back(tmp_path: Path, capsys) -> None:
    channel = f"monitor-{time.monotonic_ns()}"
    out = tmp_path / "live.log"
    frames = [
        can.Message(arbitration_id=0x1ABCDEF0, data=b"\x01\x02", is_extended_id=True),
        can.Message(arbitration_id=0x7FF, is_extended_id=False, data=bytes(range(16)), is_fd=True),
        can.Message(is_error_frame=True, arbitration_id=0x4, data=bytes(8)),
        can.Message(arbitration_id=0x07D, is_remote_frame=True, is_extended_id=False),
        can.Message(arbitration_id=0x000, data=b"", is_extended_id=False),
    ]
    with can.Bus(interface="virtual", channel=channel, receive_own_messages=False) as sender:

        def send() -> None:
            # Send once the monitor's bus has joined the channel (a virtual bus delivers only to buses open
            # when a frame is sent): a fixed sleep raced the monitor's start-up on a loaded machine.
            deadline = time.monotonic() + 30
            while len(virtual.channels.get(channel, ())) < 2 and time.monotonic() < deadline:
                time.sleep(0.01)
            for frame in frames:
                sender.send(frame)

        thread = threading.Thread(target=send)
        thread.start()
        code = main(["monitor", "-i", "virtual", "-c", channel, "--duration", "3", "--write", str(out)])
        thread.join(5)
    live = capsys.readouterr().out.splitlines()
    assert code == 0 and len(live) == 5, live
    assert "extended" in live[0] and "CAN FD" in live[1] and "error frame" in live[2]
    written = out.read_text().splitlines()
    assert len(written) == 5 and written[0].endswith("1ABCDEF0#0102")
    # The saved log decodes to the same lines.
    assert main(["monitor", str(out)]) == 0
    again = capsys.readouterr().out.splitlines()
    assert [line.split(None, 1)[1] for line in again] == [line.split(None, 1)[1] for line in live]


def test_capture_line_formats_round_trip() -> None:
    line = format_candump(1.5, "can0", 0x123, b"\xaa\xbb", is_extended=False)
    (frame,) = parse_candump([line])
    assert (frame.arbitration_id, frame.data, frame.timestamp) == (0x123, b"\xaa\xbb", 1.5)
    err = format_candump(2.0, "can0", 0x4, bytes(8), is_error=True)
    (frame,) = parse_candump([err])
    assert frame.is_error and frame.arbitration_id == 0x4
    (chunk,) = parse_hex_dump([format_hex_line(3.25, "gripper->host", b"\xaa\xaa\xaa\x01")])
    assert (chunk.direction, chunk.data, chunk.timestamp) == ("gripper->host", b"\xaa\xaa\xaa\x01", 3.25)
