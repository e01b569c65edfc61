"""Issue 43 §9 (medium): after a reconnection, an MSG on CAN was marked "two devices answer as node N" for
good (10 runs in 10): a reply delayed 40 ms across a bus failure and reopen was taken for the answer to the
first new request, and the real answer for a twin's. A reply to a request sent before the outage is a late
reply (drivers/stepfoc/can_session.py ``reset``). Sans-IO: frames and given times, no bus."""

from __future__ import annotations

from grippers.drivers.stepfoc.can_protocol import Cmd, Detection, GripperStatus, encode_status, pack_id
from grippers.drivers.stepfoc.can_session import DUPLICATE_WINDOW_S, CanSession, Delivery, DuplicateFound

NODE = 5
POLL = (NODE, int(Cmd.GRIPPER_COMMAND))
STATUS_ID = pack_id(NODE, Cmd.GRIPPER_STATUS)


def _status(position: int) -> bytes:
    return encode_status(
        GripperStatus(position, 120, True, True, Detection.AT_POSITION, False, False, False, True)
    )


def test_a_reply_delayed_across_a_reopen_is_late_not_a_twin() -> None:
    s = CanSession("bus")
    s.sent(POLL)  # before the outage
    s.gave_up(POLL)  # the bus failed: the request is waited for no more
    s.reset()  # the bus was reopened
    s.sent(POLL)  # the first new request
    first = s.received(STATUS_ID, _status(40), now=10.0)  # the old reply, 40 ms late
    assert isinstance(first, Delivery)  # indistinguishable from the new one's answer (no sequence numbers)
    second = s.received(STATUS_ID, _status(41), now=10.0 + DUPLICATE_WINDOW_S / 10)  # the real answer
    assert not isinstance(second, DuplicateFound), second
    assert s.node(NODE).duplicate is None
    s.sent(POLL)  # and the node goes on answering: the client never refuses it
    assert isinstance(s.received(STATUS_ID, _status(42), now=11.0), Delivery)


def test_a_twin_is_still_found_after_a_reopen() -> None:
    s = CanSession("bus")
    s.sent(POLL)
    s.gave_up(POLL)
    s.reset()
    s.sent(POLL)
    s.received(STATUS_ID, _status(40), now=10.0)  # the late one
    s.received(STATUS_ID, _status(40), now=10.001)  # the real answer
    s.sent(POLL)
    assert isinstance(s.received(STATUS_ID, _status(40), now=11.0), Delivery)
    event = s.received(STATUS_ID, _status(90), now=11.0 + DUPLICATE_WINDOW_S / 10)  # a second device's
    assert isinstance(event, DuplicateFound)
