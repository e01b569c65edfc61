"""The URCap ASCII codec: the lines public drivers send and the replies as the controller frames them
(docs/protocols-robotiq.md §5): a SET answered by the three bytes ``ack``, a GET by ``VAR VALUE`` and a
line end. The client takes either framing of ``ack``, ends a reply at its known form, drops what is no
reply."""

from __future__ import annotations

import socket

import pytest

from grippers.drivers.robotiq.sim import RobotiqModel, serve
from grippers.drivers.robotiq.urcap_protocol import ReplyParser, get_line, set_line


def test_set_and_get_lines() -> None:
    assert set_line(POS=255) == b"SET POS 255\n"
    assert set_line(ACT=1, GTO=1) == b"SET ACT 1 GTO 1\n"
    assert get_line("OBJ") == b"GET OBJ\n"
    for bad in ({"POS": 256}, {"XYZ": 1}, {"GTO": True}, {}):
        with pytest.raises(ValueError):
            set_line(**bad)
    with pytest.raises(ValueError):
        get_line("ATR")


def _raws(p: ReplyParser, data: bytes) -> list[str]:
    return [r.raw for r in p.feed(data)]


def test_ack_ends_at_its_three_bytes_with_or_without_a_line_end() -> None:
    p = ReplyParser()
    assert _raws(p, b"ack") == ["ack"]  # the controller's framing: nothing follows
    assert _raws(p, b"ack\n") == ["ack"]  # an older simulator's, and some gateways'
    assert _raws(p, b"ackack\r\nack") == ["ack", "ack", "ack"]
    assert _raws(p, b"ac") == [] and _raws(p, b"k") == ["ack"]  # split across reads


def test_a_value_ends_at_its_line_end_or_its_third_digit() -> None:
    p = ReplyParser()
    assert _raws(p, b"POS 12") == []  # a third digit may follow
    assert [(r.name, r.value) for r in p.feed(b"3\n")] == [("POS", 123)]
    assert _raws(p, b"PRE 077") == ["PRE 077"]  # three digits: complete without its line end
    assert [r.value for r in p.feed(b"OBJ 3\nFLT 0\n")] == [3, 0]
    assert _raws(p, b"ackSTA 3\n") == ["ack", "STA 3"]


@pytest.mark.parametrize(
    ("line", "limit"), [("POS 99999", 255), ("FLT 300", 255), ("PRE 4096", 255), ("STA 7", 3)]
)
def test_a_value_out_of_its_range_is_an_error_not_a_number(line: str, limit: int) -> None:
    (reply,) = ReplyParser().feed(line.encode() + b"\n")
    assert reply.value is None and reply.error == f"{line} is out of range (0..{limit})"


def test_a_value_of_endless_digits_is_out_of_range_not_a_crash() -> None:
    (reply,) = ReplyParser().feed(b"POS " + b"9" * 10_000 + b"\n")
    assert reply.value is None and reply.error is not None and "out of range (0..255)" in reply.error
    assert len(reply.error) < 120  # the value is quoted cut short


def test_garbage_is_dropped_up_to_the_next_reply() -> None:
    p = ReplyParser()
    assert _raws(p, b"\xff\x00nak\nxyzzy POS 40\n") == ["POS 40"]
    assert p.dropped == len(b"\xff\x00nak\nxyzzy ") and p.garbage == b"\xff\x00nak\nxyzzy "
    assert _raws(p, b"x" * 100_000 + b"GT") == [] and _raws(p, b"O 1\n") == ["GTO 1"]  # a tail kept


def _recv_some(s: socket.socket) -> bytes:
    """What ur_rtde's ``RobotiqGripper::receive`` and its Python example do: one read of up to 1024 bytes."""
    return s.recv(1024)


def test_the_simulator_frames_replies_as_the_public_clients_read_them() -> None:
    """ur_rtde's C++ ``isAck`` and its Python example compare one raw read to ``ack``; the URCap's own script
    reads exactly three bytes, then reads a GET's answer as a string ending in a line end; ur_rtde's
    ``getVars`` sends several GETs at once and splits the answer at line ends."""
    server = serve(RobotiqModel(), "urcap://127.0.0.1:0")
    try:
        server.pause()
        with socket.create_connection(("127.0.0.1", server.port), timeout=5) as s:
            s.sendall(b"SET ACT 1\n")
            assert _recv_some(s) == b"ack"  # data == b"ack", as the public clients test it
            s.sendall(b"GET STA\n")
            assert _recv_some(s) == b"STA 1\n"  # nothing left over from the ack
            server.step(1.5)
            s.sendall(b"SET POS 120 SPE 255 FOR 10 GTO 1\n")
            assert s.recv(3) == b"ack"  # socket_read_byte_list(3, ...)
            s.sendall(b"GET PRE\n")
            assert _recv_some(s).split() == [b"PRE", b"120"]
            server.step(2.0)
            s.sendall(b"GET OBJ\nGET POS\nGET STA\n")
            got = b""
            while got.count(b"\n") < 3:
                got += _recv_some(s)
            assert [line.split()[1] for line in got.split(b"\n")[:3]] == [b"3", b"120", b"3"]
    finally:
        server.close()
