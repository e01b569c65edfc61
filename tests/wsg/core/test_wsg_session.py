"""Matching rules of the sans-IO session: pending/final, auto-update routing, stale late replies."""

from __future__ import annotations

import pytest

from grippers.drivers.errors import GripperError, ProtocolError
from grippers.drivers.wsg.commands import encode_reply, encode_request
from grippers.drivers.wsg.protocol import ChecksumError, Discarded, Packet, Status, encode_packet
from grippers.drivers.wsg.session import (
    Acknowledged,
    AutoUpdate,
    Completed,
    ExchangeFailed,
    ExchangeState,
    Session,
    StaleReply,
    Unsolicited,
)


def reply(cmd: int, status: int = 0, **fields) -> bytes:
    return encode_packet(cmd, encode_reply(cmd, status, **fields))


def kinds(events) -> list[str]:
    """Event names, without the Discarded noise a rescan after a bad packet produces."""
    return [type(e).__name__ for e in events if not isinstance(e, Discarded)]


def test_immediate_reply_completes_the_exchange() -> None:
    s = Session()
    ex, raw = s.send(0x43, encode_request(0x43), now=0.0)
    assert raw == encode_packet(0x43, b"\x00\x00\x00")
    events = s.receive(reply(0x43, width=12.5), now=0.01)
    assert kinds(events) == ["Completed"]
    assert events[0].exchange is ex and ex.state is ExchangeState.DONE
    assert ex.reply == Packet(0x43, encode_reply(0x43, 0, width=12.5))
    assert not s.is_busy(0x43, 0.02)


def test_pending_then_final_reply() -> None:
    s = Session()
    ex, _ = s.send(0x21, encode_request(0x21, width=10, speed=50), now=0.0)
    events = s.receive(reply(0x21, Status.E_CMD_PENDING), now=0.01)
    assert kinds(events) == ["Acknowledged"] and ex.state is ExchangeState.PENDING
    assert ex.ack is not None and ex.ack.status == Status.E_CMD_PENDING
    assert s.is_busy(0x21, 0.02)  # the slot stays busy until the final reply
    # State queries run while the motion is pending.
    q, _ = s.send(0x43, b"\x00\x00\x00", now=0.02)
    assert kinds(s.receive(reply(0x43, width=30.0), now=0.03)) == ["Completed"]
    assert q.state is ExchangeState.DONE and ex.state is ExchangeState.PENDING
    events = s.receive(reply(0x21, Status.E_AXIS_BLOCKED), now=1.0)
    assert isinstance(events[0], Completed) and events[0].exchange is ex
    assert ex.reply is not None and ex.reply.status == Status.E_AXIS_BLOCKED


def test_immediate_error_of_an_async_command_is_final() -> None:
    s = Session()
    ex, _ = s.send(0x20, b"\x00", now=0.0)
    assert kinds(s.receive(reply(0x20, Status.E_ACCESS_DENIED), now=0.01)) == ["Completed"]
    assert ex.state is ExchangeState.DONE


def test_one_exchange_per_command_id() -> None:
    s = Session()
    s.send(0x43, b"\x00\x00\x00", now=0.0)
    assert s.is_busy(0x43, 0.0) and not s.is_busy(0x44, 0.0)
    with pytest.raises(GripperError):
        s.send(0x43, b"\x00\x00\x00", now=0.0)
    s.send(0x44, b"\x00\x00\x00", now=0.0)  # another id runs concurrently
    assert len(s.outstanding()) == 2


def test_auto_updates_are_routed_to_subscribers_never_to_a_request() -> None:
    s = Session()
    s.subscribe(0x43)
    # No request outstanding: an update.
    assert kinds(s.receive(reply(0x43, width=1.0), now=0.0)) == ["AutoUpdate"]
    # A request of ANOTHER id is outstanding: an update of 43h does not complete it.
    ex, _ = s.send(0x40, b"\x00\x00\x00", now=0.0)
    events = s.receive(reply(0x43, width=2.0) + reply(0x40, state=1), now=0.01)
    assert kinds(events) == ["AutoUpdate", "Completed"]
    assert events[1].exchange is ex
    # A motion is pending: updates keep flowing and the motion's final reply still finds its exchange.
    m, _ = s.send(0x21, encode_request(0x21, width=1, speed=1), now=0.1)
    events = s.receive(
        reply(0x21, Status.E_CMD_PENDING) + reply(0x43, width=3.0) + reply(0x43, width=4.0) + reply(0x21),
        now=0.2,
    )
    assert kinds(events) == ["Acknowledged", "AutoUpdate", "AutoUpdate", "Completed"]
    assert events[-1].exchange is m


def test_same_id_request_while_subscribed_takes_the_next_packet_of_that_id() -> None:
    s = Session()
    s.subscribe(0x43)
    ex, _ = s.send(0x43, b"\x01\x0a\x00", now=0.0)
    events = s.receive(reply(0x43, width=5.0) + reply(0x43, width=5.5), now=0.01)
    # The first packet of the id answers the request (same data as an update); the next is an update.
    assert kinds(events) == ["Completed", "AutoUpdate"]
    assert events[0].exchange is ex
    s.unsubscribe(0x43)
    assert kinds(s.receive(reply(0x43, width=6.0), now=0.02)) == ["Unsolicited"]


def test_packets_nobody_waits_for_are_unsolicited() -> None:
    s = Session()
    events = s.receive(reply(0x25) + reply(0x43, width=1.0), now=0.0)
    assert kinds(events) == ["Unsolicited", "Unsolicited"]


def test_late_reply_after_timeout_is_never_matched_to_the_next_request() -> None:
    s = Session(stale_ttl=5.0)
    old, _ = s.send(0x43, b"\x00\x00\x00", now=0.0)
    s.abandon(old, now=1.0)  # the caller timed out
    assert old.state is ExchangeState.ABANDONED
    assert s.is_busy(0x43, 1.0)  # the late reply still holds the slot
    events = s.receive(reply(0x43, width=1.0), now=1.5)
    assert kinds(events) == ["StaleReply"] and events[0].exchange is old
    assert not s.is_busy(0x43, 1.5)
    new, _ = s.send(0x43, b"\x00\x00\x00", now=1.6)
    events = s.receive(reply(0x43, width=2.0), now=1.7)
    assert kinds(events) == ["Completed"] and events[0].exchange is new
    assert new.reply is not None and new.reply.payload == encode_reply(0x43, 0, width=2.0)


def test_stale_marker_of_a_timed_out_motion_waits_for_its_final_reply() -> None:
    s = Session(stale_ttl=1.0, stale_final_ttl=30.0)
    # Timed out before the PENDING arrived: the marker swallows PENDING and then the final reply.
    ex, _ = s.send(0x25, encode_request(0x25, width=1, speed=1), now=0.0)
    s.abandon(ex, now=1.0)
    assert kinds(s.receive(reply(0x25, Status.E_CMD_PENDING), now=1.5)) == ["StaleReply"]
    assert s.is_busy(0x25, 20.0)  # the final-reply marker lives longer
    assert kinds(s.receive(reply(0x25, Status.E_CMD_FAILED), now=20.0)) == ["StaleReply"]
    assert not s.is_busy(0x25, 20.0)
    # Timed out while pending: only the final reply is swallowed.
    ex, _ = s.send(0x21, encode_request(0x21, width=1, speed=1), now=21.0)
    s.receive(reply(0x21, Status.E_CMD_PENDING), now=21.1)
    s.abandon(ex, now=22.0)
    assert kinds(s.receive(reply(0x21), now=25.0)) == ["StaleReply"]
    new, _ = s.send(0x21, encode_request(0x21, width=2, speed=1), now=26.0)
    assert kinds(s.receive(reply(0x21, Status.E_CMD_PENDING), now=26.1)) == ["Acknowledged"]


def test_stale_marker_goes_only_when_a_later_reply_proves_its_reply_lost() -> None:
    s = Session(stale_ttl=2.0)
    ex, _ = s.send(0x40, b"\x00\x00\x00", now=0.0)
    s.abandon(ex, now=1.0)
    assert s.is_busy(0x40, 2.9) and s.stale_ids(2.9) == [0x40]
    # Issue 13 item 2: no expiry on a timer alone; a reply 4 s late would answer the next request.
    assert s.is_busy(0x40, 100.0) and s.needs_barrier(0x40, 100.0) and not s.needs_barrier(0x40, 2.9)
    # The barrier: a LOOP with a fresh nonce, sent after the lost request and answered in order.
    nonce = s.barrier_payload()
    loop, _ = s.send(0x06, nonce, now=100.0)
    assert kinds(s.receive(reply(0x06, data=nonce), now=100.1)) == ["Completed"]
    assert not s.is_busy(0x40, 100.1) and s.lost_replies == 1
    new, _ = s.send(0x40, b"\x00\x00\x00", now=100.2)
    assert kinds(s.receive(reply(0x40, state=0), now=100.3)) == ["Completed"]


def test_a_proof_inside_the_reorder_margin_waits_for_the_margin() -> None:
    s = Session(stale_ttl=2.0)
    ex, _ = s.send(0x31, b"", now=0.0)
    s.abandon(ex, now=0.2)
    other, _ = s.send(0x40, b"\x00\x00\x00", now=0.3)
    s.receive(reply(0x40, state=0), now=0.4)  # a later request answered: the 31h reply is lost ...
    assert s.is_busy(0x31, 1.0)  # ... but a datagram network may still deliver it within stale_ttl
    assert not s.needs_barrier(0x31, 2.5) and not s.is_busy(0x31, 2.5)


def test_late_reply_after_the_marker_was_proved_lost_is_unsolicited_not_a_reply() -> None:
    s = Session(stale_ttl=0.5)
    ex, _ = s.send(0x33, b"", now=0.0)
    s.abandon(ex, now=0.2)
    s.send(0x40, b"\x00\x00\x00", now=0.3)
    s.receive(reply(0x40, state=0), now=0.4)
    assert not s.is_busy(0x33, 1.0)
    assert kinds(s.receive(reply(0x33, force=10.0), now=1.1)) == ["Unsolicited"]


def test_loop_replies_are_matched_by_content() -> None:
    s = Session(stale_ttl=5.0)
    a, _ = s.send(0x06, b"A", now=0.0)
    s.abandon(a, now=0.2)
    assert not s.is_busy(0x06, 0.3)  # a LOOP never waits for a LOOP marker
    b, _ = s.send(0x06, b"B", now=0.3)
    events = s.receive(reply(0x06, data=b"A") + reply(0x06, data=b"B") + reply(0x06, data=b"B"), now=4.0)
    assert kinds(events) == ["StaleReply", "Completed", "Unsolicited"]  # late A, own B, duplicated B
    assert b.reply is not None and b.reply.payload[2:] == b"B"
    c, _ = s.send(0x06, b"C", now=4.1)
    assert s.take_reply(c, reply(0x06, data=b"B")) is None  # the fast path checks the content too
    assert kinds(s.receive(reply(0x06, data=b"B"), now=4.2)) == ["Unsolicited"]
    error = reply(0x06, Status.E_CMD_FORMAT_ERROR)
    assert s.take_reply(c, error) is not None  # an error status carries no echo: it is the reply


def test_size_field_bound_per_command() -> None:
    """Issue 13 item 4: a false header claiming more than its id's reply can hold is dropped at once."""
    s = Session()
    ex, _ = s.send(0x43, b"\x00\x00\x00", now=0.0)
    false_header = b"\xaa\xaa\xaa\x43\xe8\x03"  # GET_WIDTH claiming 1,000 bytes (its reply holds 6)
    events = s.receive(false_header + reply(0x43, width=7.0), now=0.01)
    assert kinds(events) == ["BadLength", "Completed"]
    # Open-ended replies (finger data) are plausible only while a request of that id is outstanding.
    events = s.receive(b"\xaa\xaa\xaa\x63\xe8\x03" + reply(0x40, state=0), now=0.02)
    assert kinds(events)[0] == "BadLength"
    fd, _ = s.send(0x63, b"", now=0.03)
    assert s.receive(b"\xaa\xaa\xaa\x63\x10\x00", now=0.04) == []  # waits: it may be the reply
    assert s.parser.buffered


def test_abandoning_a_finished_exchange_does_nothing() -> None:
    s = Session()
    ex, _ = s.send(0x31, b"", now=0.0)
    s.receive(reply(0x31, acceleration=100.0), now=0.1)
    s.abandon(ex, now=0.2)
    assert ex.state is ExchangeState.DONE and not s.is_busy(0x31, 0.2)


def test_corrupted_reply_fails_its_exchange_at_once() -> None:
    s = Session()
    ex, _ = s.send(0x31, b"", now=0.0)
    bad = bytearray(reply(0x31, acceleration=100.0))
    bad[-1] ^= 0xFF
    events = s.receive(bytes(bad), now=0.1)
    assert kinds(events) == ["ChecksumError", "ExchangeFailed"]
    assert isinstance(events[1].error, ProtocolError) and ex.state is ExchangeState.FAILED
    assert not s.is_busy(0x31, 0.1)
    # For a subscribed id the corrupt packet may have been an update: the request keeps waiting.
    s.subscribe(0x43)
    q, _ = s.send(0x43, b"\x00\x00\x00", now=0.2)
    bad = bytearray(reply(0x43, width=1.0))
    bad[-2] ^= 0xFF
    assert kinds(s.receive(bytes(bad), now=0.3)) == ["ChecksumError"]
    assert q.state is ExchangeState.SENT


def test_reply_without_status_fails_its_exchange() -> None:
    s = Session()
    ex, _ = s.send(0x31, b"", now=0.0)
    events = s.receive(encode_packet(0x31, b"\x00"), now=0.1)
    assert isinstance(events[0], ExchangeFailed) and ex.state is ExchangeState.FAILED


def test_checksum_verification_can_be_off() -> None:
    s = Session(verify_checksum=False)
    ex, _ = s.send(0x31, b"", now=0.0)
    bad = bytearray(reply(0x31, acceleration=100.0))
    bad[-1] ^= 0xFF
    assert kinds(s.receive(bytes(bad), now=0.1)) == ["Completed"]


def test_noise_and_split_packets_between_replies() -> None:
    s = Session()
    ex, _ = s.send(0x20, b"\x00", now=0.0)
    stream = b"\x00\xaa\x13" + reply(0x20, Status.E_CMD_PENDING) + b"\xaa\xaa" + reply(0x20)
    events = []
    for i, b in enumerate(stream):
        events += s.receive(bytes([b]), now=i * 0.001)
    assert kinds(events) == ["Acknowledged", "Completed"]
    assert b"".join(e.raw for e in events if isinstance(e, Discarded)) == b"\x00\xaa\x13\xaa\xaa"


def test_silent_gap_resets_a_half_received_packet() -> None:
    s = Session()
    ex, _ = s.send(0x06, b"x", now=0.0)
    corrupt_header = b"\xaa\xaa\xaa\x06\x00\x01"  # claims 256 bytes: plausible for a LOOP reply
    events = s.receive(corrupt_header + reply(0x06, data=b"x"), now=0.01)
    assert kinds(events) == [] and ex.state is ExchangeState.SENT
    events = s.reset_parser(now=0.1)
    assert "Completed" in kinds(events) and ex.state is ExchangeState.DONE
    assert s.reset_parser(now=0.2) == []


def test_fail_all_on_connection_loss() -> None:
    s = Session()
    a, _ = s.send(0x21, encode_request(0x21, width=1, speed=1), now=0.0)
    b, _ = s.send(0x43, b"\x00\x00\x00", now=0.0)
    c, _ = s.send(0x40, b"\x00\x00\x00", now=0.0)
    s.abandon(c, now=0.5)
    error = GripperError("gone")
    assert set(s.fail_all(error)) == {a, b}
    assert a.state is b.state is ExchangeState.FAILED and a.error is error
    assert not s.is_busy(0x40, 0.6) and s.outstanding() == []


def test_events_are_typed() -> None:
    s = Session()
    s.subscribe(0x40)
    events = s.receive(reply(0x40, state=0) + b"\xaa\xaa\xaa\x40\x02\x00\x00\x00\x00\x00" + b"\x01", now=0.0)
    assert isinstance(events[0], AutoUpdate)
    assert any(isinstance(e, ChecksumError) for e in events)
    assert all(
        isinstance(e, AutoUpdate | ChecksumError | Discarded | Unsolicited | StaleReply | Acknowledged)
        for e in events
    )


def test_take_reply_completes_only_an_exact_final_reply() -> None:
    """The caller's shortcut (docs/performance.md, target 2) takes exactly one final reply and declines
    everything the general path must see, leaving the session untouched."""
    s = Session()
    ex, _ = s.send(0x43, encode_request(0x43), now=0.0)
    good = reply(0x43, width=12.5)
    assert s.take_reply(ex, good + reply(0x44, speed=1.0)) is None  # two packets: routing needed
    assert s.take_reply(ex, good[:-1]) is None  # half a packet
    assert s.take_reply(ex, reply(0x44, speed=1.0)) is None  # another id
    assert s.take_reply(ex, good[:-1] + bytes([good[-1] ^ 1])) is None  # checksum
    assert ex.state is ExchangeState.SENT and s.is_busy(0x43, 0.0)
    assert s.take_reply(ex, good) == Packet(0x43, encode_reply(0x43, 0, width=12.5))
    assert ex.state is ExchangeState.DONE and not s.is_busy(0x43, 0.0)

    motion, _ = s.send(0x21, encode_request(0x21, width=10, speed=50), now=0.0)
    assert s.take_reply(motion, reply(0x21, Status.E_CMD_PENDING)) is None  # not final
    failed, _ = s.send(0x20, b"\x00", now=0.0)
    assert s.take_reply(failed, reply(0x20, Status.E_ACCESS_DENIED)).status == Status.E_ACCESS_DENIED

    s.receive(b"\xaa\xaa", now=0.0)  # the parser holds the start of a preamble: the bytes belong together
    q, _ = s.send(0x45, encode_request(0x45), now=0.0)
    assert s.take_reply(q, reply(0x45, force=3.0)) is None


def test_a_stop_never_waits_for_the_marker_of_an_interrupted_stop() -> None:
    s = Session(stale_ttl=5.0)
    first, _ = s.send(0x22, b"", now=0.0)
    s.abandon(first, now=0.1)  # Ctrl-C while waiting for the STOP's reply
    assert not s.is_busy(0x22, 0.2) and not s.needs_barrier(0x22, 10.0)
    second, _ = s.send(0x22, b"", now=0.2)
    assert s.take_reply(second, reply(0x22)) is None  # the fast path leaves the order to receive()
    events = s.receive(reply(0x22) + reply(0x22), now=0.3)
    assert kinds(events) == ["StaleReply", "Completed"]  # in order: the first stop's reply, then its own
    assert events[0].exchange is first and events[1].exchange is second
    assert not s.is_busy(0x20, 0.3)
