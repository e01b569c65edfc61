"""The URCap ASCII codec: the lines public drivers send (docs/protocols-robotiq.md §5) and their replies."""

from __future__ import annotations

import pytest

from grippers.drivers.robotiq.urcap import LineParser, get_line, set_line


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
