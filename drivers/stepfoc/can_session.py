"""Request/reply matching for one STEPFOC CAN bus (sans-IO: frames and time in, deliveries out).

The protocol has no sequence numbers: a reply is matched by (node, command) only, its *key*, and a 60 status
answers a 61 command (both key (node, 61)). So at most one request per key is outstanding at a time; the
client enforces that (a lock per key) and tells this session when it sends one (:meth:`CanSession.sent`)
and when it stops waiting for it (:meth:`CanSession.gave_up`). Everything a frame means is decided here:

* **Not ours.** Error frames, extended identifiers and 11-bit identifiers above 0x7FF (a virtual or
  multicast bus carries whatever a program sends) are ignored (:func:`is_stepfoc_frame`).
* **Another host's request** (a host-to-node frame, a remote frame, or an unknown command) is never a reply.
  A 61 or a remote request of a command that has a reply raises the number of replies expected for its key,
  so the node's answer to it is not taken for a second device.
* **A reply** to a key this client waits for is a :class:`Delivery` of the decoded :class:`Message`, or of
  a :class:`~grippers.drivers.errors.ProtocolError` when it cannot be decoded (the waiting request fails at
  once rather than running into its timeout). A reply nobody waits for still updates the node's facts.
* **Late replies.** A request given up (timed out, abandoned, cancelled) leaves its count: its late reply
  is then expected, never a twin's, and is delivered to nobody unless a new request of that key waits. A
  late reply is indistinguishable from the reply to the next request with the same key; for 60 that is
  harmless (any 60 is a fresh status of the node); for remote requests it returns the same kind of value.
* **Duplicate node ids.** Two devices with one node id answer every request twice. Per key, the requests
  seen on the bus (this client's and other hosts') are counted against the replies; a reply nobody asked for
  that arrives within :data:`DUPLICATE_WINDOW_S` of the reply to one of this client's requests marks the
  node as duplicated (:class:`DuplicateFound`, once; :attr:`NodeFacts.duplicate` from then on), and the
  client refuses every later request to it. An unsolicited frame at any other time is only ignored: a bus
  tool may send anything.
* **Our own frames.** A bus that delivers what this client sends back to it (python-can's ``udp_multicast``:
  the operating system loops every multicast datagram back to its sender, whatever python-can's
  ``receive_own_messages`` says) would make each of our requests count twice, once as another host's, so a
  twin's reply would always find a request to answer and duplicate node ids would go unseen. With
  ``echoes=True`` the session is told each frame before it goes out (:meth:`CanSession.sending`) and drops the
  first identical frame that comes back, in order, within :data:`ECHO_WINDOW_S`. Identical frames are
  interchangeable, so which of two identical frames is taken for the echo changes no count.
* **Per node facts** (:class:`NodeFacts`): the error bit of the last identifier it sent, its last status,
  the duplicate finding and the time of its last heartbeat (a :class:`Heartbeat` event).

Not thread-safe: the client calls it under one lock.
"""

from __future__ import annotations

from collections import deque
from dataclasses import dataclass

from ..errors import ProtocolError
from .can_protocol import COMMANDS, Cmd, Direction, GripperStatus, Message, decode_frame, unpack_id

__all__ = [
    "DUPLICATE_WINDOW_S",
    "ECHO_WINDOW_S",
    "CanSession",
    "Delivery",
    "DuplicateFound",
    "Event",
    "Heartbeat",
    "Key",
    "NodeFacts",
    "is_stepfoc_frame",
]

DUPLICATE_WINDOW_S = 0.05  # two nodes with one id answer one request within microseconds of each other
ECHO_WINDOW_S = 1.0  # an own frame looped back later than this was lost (a full socket buffer): forgotten

Key = tuple[int, int]  # (node, command of the request)

_STATUS = int(Cmd.GRIPPER_STATUS)
_COMMAND = int(Cmd.GRIPPER_COMMAND)
_HEARTBEAT = int(Cmd.HEARTBEAT)


@dataclass(slots=True)
class NodeFacts:
    """What the frames of one node id said."""

    error_bit: bool = False  # of the last identifier it sent (set while it has an active error)
    status: GripperStatus | None = None  # its last 60
    duplicate: str | None = None  # why this node id is taken to be answered by two devices
    heartbeat: float | None = None  # the ``now`` of its last heartbeat


@dataclass(frozen=True, slots=True)
class Delivery:
    """The reply to the request waiting on ``key``: ``message``, or ``error`` if it could not be decoded."""

    key: Key
    message: Message | None = None
    error: ProtocolError | None = None


@dataclass(frozen=True, slots=True)
class Heartbeat:
    node: int
    at: float


@dataclass(frozen=True, slots=True)
class DuplicateFound:
    """``node`` was just found to be answered by two devices (reported once)."""

    node: int
    reason: str


@dataclass(frozen=True, slots=True)
class OwnEcho:
    """This client's own frame, handed back by a bus that ``echoes``: nothing for the protocol, and not
    a frame to log again (it was logged as it went out)."""


OWN_ECHO = OwnEcho()

Event = Delivery | Heartbeat | DuplicateFound | OwnEcho


def is_stepfoc_frame(arbitration_id: int, *, error_frame: bool = False, extended: bool = False) -> bool:
    """Could this frame belong to the protocol at all (a base-format data or remote frame)?"""
    return not (error_frame or extended or arbitration_id > 0x7FF)


def reply_key(node: int, command: int) -> Key:
    """The key of the request a reply of ``command`` answers: a 60 answers a 61."""
    return (node, _COMMAND if command == _STATUS else command)


class CanSession:
    """The matching state of one bus: expected replies per key, keys waited for, per-node facts."""

    def __init__(self, device: str = "can", *, echoes: bool = False) -> None:
        self.device = device  # names the node in a ProtocolError of a reply
        self.echoes = echoes  # the bus hands this client's own frames back (module docstring)
        self._own: deque[tuple[int, bytes, bool, float]] = deque()  # sent, their echo not yet back
        self._expected: dict[Key, int] = {}  # requests seen minus replies seen, per key
        self._before_outage: dict[Key, int] = {}  # of those, the ones counted before the bus was reopened
        self._answered: dict[Key, float] = {}  # time of the last reply to one of this client's requests
        self._waiting: set[Key] = set()  # keys whose request waits for its reply
        self._nodes: dict[int, NodeFacts] = {}

    def node(self, node: int) -> NodeFacts:
        facts = self._nodes.get(node)
        if facts is None:
            facts = self._nodes[node] = NodeFacts()
        return facts

    def waiting(self, key: Key) -> bool:
        return key in self._waiting

    def sent(self, key: Key) -> None:
        """This client sent a request of ``key`` and waits for its reply."""
        self._expected[key] = self._expected.get(key, 0) + 1
        self._waiting.add(key)

    def sending(self, arbitration_id: int, data: bytes, *, remote: bool, now: float) -> None:
        """This client is about to send this frame (before it goes: its echo may come back at once). Kept
        only on a bus that ``echoes``; a frame that then fails to go out is forgotten after ECHO_WINDOW_S."""
        if self.echoes:
            self._own.append((arbitration_id, bytes(data), remote, now))

    def _own_echo(self, arbitration_id: int, data: bytes | bytearray, remote: bool, now: float) -> bool:
        own = self._own
        while own and now - own[0][3] > ECHO_WINDOW_S:
            own.popleft()
        if own and own[0][0] == arbitration_id and own[0][2] == remote and own[0][1] == data:
            own.popleft()
            return True
        return False

    def gave_up(self, key: Key) -> None:
        """The request of ``key`` no longer waits (answered, timed out, abandoned, failed). Its count stays:
        a late reply is expected, not a twin's."""
        self._waiting.discard(key)

    def reset(self) -> None:
        """The bus was reopened: requests counted before the outage are waited for by nobody, but may still
        be answered (a reply delayed across the failure and the reopen): such a reply is a late one, never
        a twin's (issue 43 §9: 40 ms late, it was taken for the answer to the first new request and the
        real answer for a second device's, for good). Kept apart from the new requests' counts."""
        for key, left in self._expected.items():
            if left > 0:
                self._before_outage[key] = self._before_outage.get(key, 0) + left
        self._expected.clear()
        self._answered.clear()
        self._own.clear()

    def received(
        self,
        arbitration_id: int,
        data: bytes | bytearray,
        *,
        now: float,
        remote: bool = False,
        error_frame: bool = False,
        extended: bool = False,
    ) -> Event | None:
        """One frame from the bus at time ``now``: what it means for this client (module docstring)."""
        if not is_stepfoc_frame(arbitration_id, error_frame=error_frame, extended=extended):
            return None
        if self._own and self._own_echo(arbitration_id, data, remote, now):
            return OWN_ECHO  # our own frame, handed back by the bus
        node, command, error = unpack_id(arbitration_id)
        spec = COMMANDS.get(command)
        if remote or spec is None or spec.direction is Direction.HOST_TO_NODE:
            # another host's request: its reply is expected too, and must not count as a second device
            if spec is not None and (command == _COMMAND or (remote and spec.remote)):
                key = (node, command)
                self._expected[key] = self._expected.get(key, 0) + 1
            return None
        facts = self.node(node)
        facts.error_bit = error
        if command == _HEARTBEAT:
            try:
                decode_frame(arbitration_id, data, False)
            except ProtocolError:
                return None  # a malformed heartbeat is not one
            facts.heartbeat = now
            return Heartbeat(node, now)
        key = reply_key(node, command)
        waiting = key in self._waiting
        found: DuplicateFound | None = None
        left = self._expected.get(key, 0)
        if left > 0:
            self._expected[key] = left - 1
            if waiting:
                self._answered[key] = now  # the reply to OUR request: a second one would be a twin
        elif self._before_outage.get(key, 0) > 0:
            self._before_outage[key] -= 1  # a late reply to a request sent before the bus was reopened
        elif facts.duplicate is None and now - self._answered.get(key, -1e9) < DUPLICATE_WINDOW_S:
            facts.duplicate = (
                f"two devices answer as node {node}: a second {spec.name} reply arrived for one "
                "request (give every gripper on the bus its own node id)"
            )
            found = DuplicateFound(node, facts.duplicate)
        try:
            decoded = decode_frame(arbitration_id, data, False)
        except ProtocolError as exc:
            if not waiting:
                return found
            self._waiting.discard(key)
            err = ProtocolError(exc.message, device=f"{self.device} node {node}", command=spec.name)
            return Delivery(key, error=err)
        if command == _STATUS:
            facts.status = decoded.value
        if not waiting:
            return found
        self._waiting.discard(key)
        return Delivery(key, decoded)
