"""`grippers monitor` decodes captures (WSG hex dumps and raw files, candump logs of both families) and live
traffic (a WSG TCP session through --proxy, a CAN bus)."""

from __future__ import annotations

import json
import signal
import subprocess
import sys
import threading
import time
from pathlib import Path

import pytest

from .conftest import monitor_proxy

VECTORS = Path("/work/shared/spec/wsg-vectors.json")
ROOT = Path(__file__).resolve().parents[2]


def _vectors() -> list[dict]:
    if VECTORS.exists():
        return json.loads(VECTORS.read_text())["packets"]
    # Some of the manual's examples (wsg-vectors.json), in case the spec folder is not there.
    return [
        {"hex": "AAAAAA010000E810", "direction": "host->gripper"},
        {"hex": "AAAAAA2002000000B3FD", "direction": "gripper->host"},
        {"hex": "AAAAAA2102001A0067CB", "direction": "gripper->host"},
    ]


def _records(r) -> list[dict]:
    assert r.returncode == 0, (r.stdout, r.stderr)
    return r.json_lines()


def test_hex_dump_with_directions(tmp_path: Path, cli) -> None:
    lines = []
    for i, v in enumerate(_vectors()):
        mark = ">" if v["direction"] == "host->gripper" else "<"
        lines.append(f"({i}.5) {mark} {' '.join(v['hex'][j : j + 2] for j in range(0, len(v['hex']), 2))}")
    capture = tmp_path / "wsg.hex"
    capture.write_text("# WSG manual examples\n" + "\n".join(lines) + "\n")
    docs = _records(cli("monitor", str(capture), "--json"))
    assert len(docs) == len(_vectors())
    assert [d["direction"] for d in docs] == [v["direction"] for v in _vectors()]
    assert docs[0]["id"] == "01h" and docs[0]["time"] == 0.5
    assert all(d["protocol"] == "wsg" and d["raw"] for d in docs)
    homing = next(d for d in docs if d["id"] == "20h")
    assert "HOMING" in homing["command"] and homing["status"] == "E_SUCCESS"
    text = cli("monitor", str(capture))
    assert text.returncode == 0 and len(text.stdout.splitlines()) == len(docs)
    assert "E_CMD_PENDING" in text.stdout


def test_direction_is_inferred_from_the_layout(tmp_path: Path, cli) -> None:
    from grippers.drivers.wsg import Cmd, encode_packet, encode_reply, encode_request

    move = encode_packet(
        Cmd.PREPOSITION,
        encode_request(Cmd.PREPOSITION, relative=False, stop_on_block=True, width=40.0, speed=50.0),
    )
    width = encode_packet(Cmd.GET_WIDTH, encode_reply(Cmd.GET_WIDTH, width=40.0))
    capture = tmp_path / "mixed.hex"
    capture.write_text(f"{move.hex()}\n{width.hex()}\n")
    docs = _records(cli("monitor", str(capture), "--json"))
    assert [d["direction"] for d in docs] == ["host->gripper", "gripper->host"]
    assert docs[0]["fields"]["width"] == 40.0 and docs[1]["fields"]["width"] == 40.0


def test_raw_byte_file_split_anywhere(tmp_path: Path, cli) -> None:
    blob = b"\x00\xaa" + b"".join(
        bytes.fromhex(v["hex"]) for v in _vectors() if v["direction"] == "gripper->host"
    )
    capture = tmp_path / "wsg.bin"
    capture.write_bytes(blob)
    docs = _records(cli("monitor", str(capture), "--direction", "from", "--json"))
    packets = [d for d in docs if d["status"] != "noise"]
    assert len(packets) == sum(v["direction"] == "gripper->host" for v in _vectors())
    assert all(d["direction"] == "gripper->host" for d in docs)
    assert docs[0]["status"] == "noise" and docs[0]["raw"] == "00aa"  # stray bytes before the first packet


def test_garbage_capture_exits_1(tmp_path: Path, cli) -> None:
    capture = tmp_path / "noise.bin"
    capture.write_bytes(bytes(range(256)) * 4)
    r = cli("monitor", str(capture))
    assert r.returncode == 1 and "no complete packet" in r.one_error_line()


def test_a_cut_packet_is_reported_not_dropped(tmp_path: Path, cli) -> None:
    capture = tmp_path / "cut.hex"
    capture.write_text("< AA AA AA 21 02 00 00 00 28 04\n< AA AA AA 43 06 00 00\n")
    docs = _records(cli("monitor", str(capture), "--json"))
    assert [d["status"] for d in docs] == ["E_SUCCESS", "noise"]
    assert "incomplete" in docs[1]["fields"]["reason"]


def test_missing_capture_is_a_usage_error(tmp_path: Path, cli) -> None:
    r = cli("monitor", str(tmp_path / "nope.log"))
    assert r.returncode == 2 and "cannot read" in r.one_error_line()


def test_candump_log_of_stepfoc_frames(tmp_path: Path, cli) -> None:
    # id = node << 7 | command << 1 | error (docs/protocols.md §2); node 2: 61 poll, 60 reply, 10 ping (RTR).
    node = 2
    poll = node << 7 | 61 << 1
    reply = node << 7 | 60 << 1
    ping = node << 7 | 10 << 1
    capture = tmp_path / "msg.log"
    capture.write_text(
        f"(1700000000.000100) can0 {poll:03X}#\n"
        f"(1700000000.000300) can0 {reply:03X}#80FE0C41\n"
        f"(1700000000.000400) can0 {ping:03X}#R\n"
    )
    docs = _records(cli("monitor", str(capture), "--json"))
    assert len(docs) == 3
    assert all(d["protocol"] == "stepfoc" and d["node"] == node for d in docs)
    assert [d["command"] for d in docs] == ["gripper_command", "gripper_status", "ping"]
    assert [d["direction"] for d in docs] == ["host->gripper", "gripper->host", "host->gripper"]
    assert docs[2]["raw"] == "R"
    # 80 FE0C 41: position 128, -500 mA (big-endian), flags action + calibrated (docs/protocols.md §2)
    assert docs[1]["fields"]["position"] == 128 and docs[1]["fields"]["current_ma"] == -500
    assert docs[1]["fields"]["calibrated"] is True and docs[1]["fields"]["detection"] == "MOVING"


def test_candump_log_of_wsg_over_can(tmp_path: Path, cli) -> None:
    base = 0x10
    packet = bytes.fromhex("AAAAAA300600000000001643DCCB")  # 14 bytes: one full frame and one of 6
    lines = [
        f"(1.0) can0 {base:03X}#{bytes.fromhex('AAAAAA010000E810').hex().upper()}",
        f"(1.1) can0 {base + 1:03X}#{packet[:8].hex().upper()}",
        f"(1.2) can0 {base + 1:03X}#{packet[8:].hex().upper()}",
    ]
    capture = tmp_path / "wsg-can.log"
    capture.write_text("\n".join(lines) + "\n")
    docs = _records(cli("monitor", str(capture), "--protocol", "wsg", "--can-id", hex(base), "--json"))
    assert [d["direction"] for d in docs] == ["host->gripper", "gripper->host"]
    assert docs[1]["id"] == "30h" and docs[1]["time"] == 1.2  # reassembled from two frames
    # --protocol auto finds the same packets among STEPFOC frames.
    auto = _records(cli("monitor", str(capture), "--can-id", hex(base), "--json"))
    assert [d["protocol"] for d in auto] == ["wsg", "wsg"]


def test_stdin_capture(cli) -> None:
    r = cli("monitor", "-", stdin="(5.0) can0 47A#\n")
    assert r.returncode == 0 and "gripper_command poll" in r.stdout


def test_proxy_decodes_a_live_wsg_tcp_session(start_sim, cli) -> None:
    target = start_sim("wsg", "--listen", "tcp://127.0.0.1:0").url.split("://", 1)[1]
    with monitor_proxy("--proxy", "127.0.0.1:0", "--to", target, "--json", stop_timeout=10) as proxy:
        for command in (("home",), ("move", "50")):
            r = cli(command[0], f"wsg+tcp://127.0.0.1:{proxy.port}", *command[1:], "--timeout", "2")
            assert r.returncode == 0, r.stderr
    docs = [json.loads(x) for x in proxy.out.splitlines()]
    commands = [(d["direction"], d["command"], d["status"]) for d in docs]
    assert ("host->gripper", "PREPOSITION (21h)", None) in commands
    assert ("gripper->host", "PREPOSITION (21h)", "E_CMD_PENDING") in commands
    assert ("gripper->host", "PREPOSITION (21h)", "E_SUCCESS") in commands
    move = next(d for d in docs if d["command"] == "PREPOSITION (21h)")
    assert move["fields"]["width"] == 50.0


@pytest.mark.udp_multicast
def test_live_can_bus(start_sim, cli, mcast_channel: str) -> None:
    node = 11
    url = start_sim("msg", "--listen", f"can://udp_multicast/{mcast_channel}?node={node}").url
    proc = subprocess.Popen(
        [
            sys.executable,
            "-m",
            "grippers",
            "monitor",
            "-i",
            "udp_multicast",
            "-c",
            mcast_channel,
            "--json",
            "--duration",
            "20",
        ],
        cwd=ROOT,
        stdout=subprocess.PIPE,
        text=True,
    )
    lines: list[str] = []
    reader = threading.Thread(target=lambda: lines.extend(proc.stdout or ()), daemon=True)
    reader.start()

    def seen() -> set[str]:
        docs = [json.loads(x) for x in list(lines)]
        return {d["command"] for d in docs if d["node"] == node}

    try:
        # The monitor needs a moment to start and join the group, longer on a busy machine than any fixed
        # pause (issue 33 §5): ask until it has shown our exchange, bounded.
        deadline = time.monotonic() + 15.0
        while not {"gripper_command", "gripper_status"} <= seen() and time.monotonic() < deadline:
            assert cli("state", url, "--timeout", "2").returncode == 0
            time.sleep(0.2)
    finally:
        proc.send_signal(signal.SIGINT)
        proc.wait(timeout=10)
        reader.join(10)
    assert {"gripper_command", "gripper_status"} <= seen()
