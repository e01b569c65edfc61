"""The URCap ASCII codec: the lines public drivers send (docs/protocols-robotiq.md §5) and their replies."""

from __future__ import annotations

import pytest

from grippers.drivers.robotiq.urcap_protocol import LineParser, get_line, set_line


def test_set_and_get_lines() -> None:
    assert set_line(POS=255) == b"SET POS 255\n"
    assert set_line(ACT=1, GTO=1) == b"SET ACT 1 GTO 1\n"
    assert get_line("OBJ") == b"GET OBJ\n"
    for bad in ({"POS": 256}, {"XYZ": 1}, {"GTO": True}, {}):
        with pytest.raises(ValueError):
            set_line(**bad)
    with pytest.raises(ValueError):
        get_line("ATR")


def test_replies_split_across_reads() -> None:
    p = LineParser()
    assert p.feed(b"ac") == []
    (ack, pos) = p.feed(b"k\nPOS 12")[:1] + p.feed(b"3\n")
    assert ack.name is None and (pos.name, pos.value) == ("POS", 123)
    with pytest.raises(ValueError, match="not a URCap reply"):
        p.feed(b"nak\n")
    with pytest.raises(ValueError, match="no end of line"):
        p.feed(b"x" * 300)


def test_the_simulated_urcap_answers_the_lines_public_drivers_send() -> None:
    import socket

    from grippers.drivers.robotiq.sim import RobotiqModel, serve

    server = serve(RobotiqModel(), "urcap://127.0.0.1:0")
    try:
        server.pause()
        with socket.create_connection(("127.0.0.1", server.port), timeout=5) as s:
            p = LineParser()

            def ask(line: bytes) -> str:
                s.sendall(line)
                while True:
                    got = p.feed(s.recv(100))
                    if got:
                        return got[0].raw

            assert ask(b"SET ACT 1\n") == "ack"
            assert ask(b"GET STA\n") == "STA 1"  # activation in progress
            server.step(1.5)
            assert ask(b"GET STA\n") == "STA 3"
            assert ask(b"SET POS 120 SPE 255 FOR 10 GTO 1\n") == "ack"
            assert ask(b"GET PRE\n") == "PRE 120"
            server.step(2.0)
            assert ask(b"GET OBJ\n") == "OBJ 3" and ask(b"GET POS\n") == "POS 120"
    finally:
        server.close()
