"""The sans-IO CAN session over frames and given times: which request a frame answers, and what it says about
its node (drivers/stepfoc/can_session.py). No bus, no threads, no clock."""

from __future__ import annotations

import pytest

from grippers.drivers.errors import ProtocolError
from grippers.drivers.stepfoc.can_protocol import (
    Cmd,
    Detection,
    GripperCommand,
    GripperStatus,
    encode_command,
    encode_frame,
    encode_status,
    pack_id,
)
from grippers.drivers.stepfoc.can_session import (
    DUPLICATE_WINDOW_S,
    ECHO_WINDOW_S,
    OWN_ECHO,
    CanSession,
    Delivery,
    DuplicateFound,
    Heartbeat,
)

NODE = 3
POLL = (NODE, int(Cmd.GRIPPER_COMMAND))  # a 60 answers the 61 key
STATUS_ID = pack_id(NODE, Cmd.GRIPPER_STATUS)


def status(position: int = 40) -> GripperStatus:
    return GripperStatus(position, 120, True, True, Detection.AT_POSITION, False, False, False, True)


def status_bytes(position: int = 40) -> bytes:
    return encode_status(status(position))


def test_a_status_answers_the_waiting_poll_and_is_the_nodes_last_status() -> None:
    s = CanSession("bus")
    s.sent(POLL)
    event = s.received(STATUS_ID, status_bytes(40), now=1.0)
    assert isinstance(event, Delivery) and event.key == POLL and event.error is None
    assert event.message is not None and event.message.value.position == 40
    assert s.node(NODE).status is not None and s.node(NODE).status.position == 40
    assert not s.waiting(POLL)  # answered: the next 60 goes to nobody
    assert s.received(STATUS_ID, status_bytes(41), now=1.2) is None
    assert s.node(NODE).status.position == 41  # still the node's latest


def test_a_reply_of_another_key_or_node_is_not_delivered() -> None:
    s = CanSession()
    s.sent(POLL)
    assert s.received(pack_id(NODE + 1, Cmd.GRIPPER_STATUS), status_bytes(), now=1.0) is None
    assert s.received(pack_id(NODE, Cmd.TEMPERATURE), b"\x00\x19", now=1.0) is None
    assert s.waiting(POLL)


def test_a_twins_second_reply_marks_the_node_duplicated_once() -> None:
    s = CanSession()
    s.sent(POLL)
    assert isinstance(s.received(STATUS_ID, status_bytes(40), now=1.0), Delivery)
    event = s.received(STATUS_ID, status_bytes(90), now=1.0 + DUPLICATE_WINDOW_S / 10)
    assert isinstance(event, DuplicateFound) and event.node == NODE
    assert "two devices answer as node 3" in (s.node(NODE).duplicate or "")
    s.sent(POLL)
    s.received(STATUS_ID, status_bytes(40), now=2.0)
    assert s.received(STATUS_ID, status_bytes(90), now=2.0 + DUPLICATE_WINDOW_S / 10) is None  # said once


def test_an_unsolicited_reply_long_after_ours_is_only_ignored() -> None:
    s = CanSession()
    s.sent(POLL)
    s.received(STATUS_ID, status_bytes(), now=1.0)
    assert s.received(STATUS_ID, status_bytes(), now=1.0 + 2 * DUPLICATE_WINDOW_S) is None
    assert s.node(NODE).duplicate is None


def test_another_hosts_request_and_its_reply_are_not_a_twin() -> None:
    s = CanSession()
    s.sent(POLL)
    assert isinstance(s.received(STATUS_ID, status_bytes(40), now=1.0), Delivery)
    # another host polls the same node (an empty 61: a request, never a reply), then the node answers it
    assert s.received(pack_id(NODE, Cmd.GRIPPER_COMMAND), b"", now=1.001) is None
    assert s.received(STATUS_ID, status_bytes(40), now=1.002) is None
    # and a 5-byte 61 of another host is one too
    command = encode_command(GripperCommand(10, 10, 300, True, True, False))
    assert s.received(pack_id(NODE, Cmd.GRIPPER_COMMAND), command, now=1.003) is None
    assert s.received(STATUS_ID, status_bytes(40), now=1.004) is None
    assert s.node(NODE).duplicate is None


def test_remote_frames_are_requests_and_raise_the_expected_count() -> None:
    s = CanSession()
    key = (NODE, int(Cmd.TEMPERATURE))
    temp_id = pack_id(NODE, Cmd.TEMPERATURE)
    s.sent(key)
    reply = encode_frame(NODE, Cmd.TEMPERATURE, 31).data
    event = s.received(temp_id, reply, now=1.0)
    assert isinstance(event, Delivery) and event.message is not None and event.message.value == 31
    # another host's remote request of the same key: its reply is expected, not a second device's
    assert s.received(temp_id, b"", remote=True, now=1.001) is None
    assert s.received(temp_id, reply, now=1.002) is None
    assert s.node(NODE).duplicate is None
    # without that request the same reply would have been a twin's
    assert isinstance(s.received(temp_id, reply, now=1.003), DuplicateFound)


def test_a_late_reply_to_a_request_given_up_is_expected_and_goes_to_nobody() -> None:
    s = CanSession()
    s.sent(POLL)
    s.gave_up(POLL)  # timed out, abandoned or cancelled
    assert s.received(STATUS_ID, status_bytes(), now=1.0) is None
    assert s.node(NODE).duplicate is None


def test_a_late_reply_answers_the_next_request_of_its_key() -> None:
    """The protocol's known limit (no sequence numbers): the late 60 is a fresh status all the same."""
    s = CanSession()
    s.sent(POLL)
    s.gave_up(POLL)
    s.sent(POLL)
    first = s.received(STATUS_ID, status_bytes(40), now=1.0)
    assert isinstance(first, Delivery)
    assert s.received(STATUS_ID, status_bytes(41), now=1.001) is None  # the second reply: expected, no twin
    assert s.node(NODE).duplicate is None


def test_heartbeat_sets_the_nodes_time_and_error_bit() -> None:
    s = CanSession()
    event = s.received(pack_id(NODE, Cmd.HEARTBEAT, error=True), b"", now=7.5)
    assert event == Heartbeat(NODE, 7.5)
    assert s.node(NODE).heartbeat == 7.5 and s.node(NODE).error_bit
    s.received(STATUS_ID, status_bytes(), now=8.0)
    assert not s.node(NODE).error_bit  # the last identifier decides


@pytest.mark.parametrize("data", [b"\x01", b"\x01\x02\x03\x04\x05\x06"])
def test_malformed_reply_is_a_protocol_error_for_the_waiting_key(data: bytes) -> None:
    s = CanSession("can0")
    s.sent(POLL)
    event = s.received(STATUS_ID, data, now=1.0)
    assert isinstance(event, Delivery) and event.key == POLL and event.message is None
    assert isinstance(event.error, ProtocolError)
    assert event.error.device == f"can0 node {NODE}" and event.error.command == "gripper_status"
    assert not s.waiting(POLL)
    assert s.received(STATUS_ID, data, now=2.0) is None  # nobody waits: ignored


@pytest.mark.parametrize(
    "kind", [{"error_frame": True}, {"extended": True}, {"arbitration_id": 0x800}], ids=str
)
def test_error_and_extended_frames_are_ignored(kind: dict[str, object]) -> None:
    s = CanSession()
    s.sent(POLL)
    arbitration_id = kind.pop("arbitration_id", STATUS_ID)
    assert isinstance(arbitration_id, int)
    flags = {k: bool(v) for k, v in kind.items()}
    assert s.received(arbitration_id, status_bytes(), now=1.0, **flags) is None
    assert s.waiting(POLL) and s.node(NODE).status is None


def test_reset_forgets_the_counts() -> None:
    """After the bus was reopened, requests counted before the outage are not waited for as replies."""
    s = CanSession()
    s.sent(POLL)
    s.gave_up(POLL)
    s.reset()
    assert s.received(STATUS_ID, status_bytes(), now=1.0) is None  # not expected, but no reply of ours yet
    assert s.node(NODE).duplicate is None


POLL_ID = pack_id(NODE, Cmd.GRIPPER_COMMAND)


def poll_with_echo(s: CanSession, now: float) -> None:
    """What a client on python-can's udp_multicast bus does: sends an empty 61 and gets it back."""
    s.sending(POLL_ID, b"", remote=False, now=now)
    s.sent(POLL)
    assert s.received(POLL_ID, b"", now=now + 0.0001) is (OWN_ECHO if s.echoes else None)


@pytest.mark.parametrize("echoes", [True, False])
def test_on_a_bus_that_echoes_a_twin_is_still_found(echoes: bool) -> None:
    """Our own poll handed back by the bus is not another host's request: without knowing it, the twin's
    second reply finds that phantom request to answer and goes unseen (as it did over udp_multicast)."""
    s = CanSession(echoes=echoes)
    poll_with_echo(s, 1.0)
    assert isinstance(s.received(STATUS_ID, status_bytes(40), now=1.001), Delivery)
    event = s.received(STATUS_ID, status_bytes(90), now=1.001 + DUPLICATE_WINDOW_S / 10)
    assert isinstance(event, DuplicateFound) is echoes


def test_an_echo_is_matched_in_order_and_another_hosts_request_still_counts() -> None:
    s = CanSession(echoes=True)
    poll_with_echo(s, 1.0)
    assert isinstance(s.received(STATUS_ID, status_bytes(40), now=1.001), Delivery)
    # another host's poll (nothing of ours outstanding): counted, so the node's answer to it is no twin
    assert s.received(POLL_ID, b"", now=1.002) is None
    assert s.received(STATUS_ID, status_bytes(40), now=1.003) is None
    assert s.node(NODE).duplicate is None


def test_an_own_frame_whose_echo_never_came_is_forgotten() -> None:
    """A frame whose echo never came (it failed to go out, or the echo was lost) must not shift the
    matching: kept, it would take our next echo, and our next frame would swallow another host's request,
    whose reply would then pass for a twin's."""
    s = CanSession(echoes=True)
    s.sending(POLL_ID, b"", remote=False, now=1.0)  # never comes back
    later = 1.0 + ECHO_WINDOW_S + 0.1
    poll_with_echo(s, later)
    assert isinstance(s.received(STATUS_ID, status_bytes(40), now=later + 0.001), Delivery)
    assert s.received(POLL_ID, b"", now=later + 0.002) is None  # another host's poll: counted
    assert s.received(STATUS_ID, status_bytes(40), now=later + 0.003) is None  # its reply: no twin
    assert s.node(NODE).duplicate is None


def test_a_bus_without_echo_keeps_nothing() -> None:
    s = CanSession()
    s.sending(POLL_ID, b"", remote=False, now=1.0)
    s.sent(POLL)
    assert s.received(POLL_ID, b"", now=1.001) is None  # another host's identical poll: counted
    assert s.received(STATUS_ID, status_bytes(40), now=1.002) is not None  # ours is answered
    assert s.received(STATUS_ID, status_bytes(40), now=1.003) is None  # and theirs is expected
    assert s.node(NODE).duplicate is None
