"""A WSG gripper as a pure state machine over packets, advanced in simulated time.

The model owns no clock, socket or thread: a server passes the time in (``handle(packet, now)``,
``advance(now)``) and writes the reply packets it gets back. That keeps every rule of the manuals testable by
direct calls, and lets one model be served over any transport. Byte layouts come from
:mod:`grippers.drivers.wsg.protocol` and :mod:`grippers.drivers.wsg.commands` only (the client's own codec),
so the simulator can never disagree with the client about a layout without a test noticing.

Connections: a gripper keeps per-connection state (07h, auto updates, where an async final reply goes), so the
model numbers its connections. Connection 0 exists from the start and is connection-oriented (TCP-like); a
server registers one per TCP client, UDP peer, pty or CAN bus with :meth:`WsgModel.connect`.

Sources: WSG command set reference 4.0.x (``000_…``), 2.2.0 (``002_…``), docs/protocols.md §1. Choices the
manuals leave open are marked "sim choice" and listed in :data:`SIM_CHOICES`; what is left out is listed
in :data:`NOT_MODELLED`.
"""

from __future__ import annotations

import math
import struct
from collections.abc import Callable
from dataclasses import dataclass, field
from typing import cast

from ...errors import ProtocolError
from ..commands import (
    COMMANDS,
    Cmd,
    FingerFlags,
    FingerType,
    FirmwareVersion,
    GraspingState,
    SystemFlags,
    available,
    decode_request,
    encode_reply,
)
from ..protocol import Packet, Status, encode_packet
from .motion import Trapezoid

# What the simulator leaves out; the lead copies this into the issue note.
NOT_MODELLED = (
    "internal gripping: the part (part_width_mm) is external, met only by closing fingers",
    "contact dynamics: a motion is planned to stop at the part; holding force = the force limit exactly",
    "blocking in the positive direction (SF_BLOCKED_PLUS is never set); obstacles during homing",
    "E_TIMEOUT, E_INSUFFICIENT_RESOURCES, E_IO_ERROR, finger over-current, finger POWER/COMM faults",
    "SF_TEMP_*, SF_POWER_FAULT, SF_CURR_FAULT, SF_FINGER_FAULT, scripts (SF_SCRIPT_*); constant temperature",
    "FAST STOP when fingers enter the soft-limit area: targets outside are refused up front (E_RANGE_ERROR) "
    "and grip travel is cut at the limit",
    "deceleration on stop/FAST STOP (the fingers stop at once); velocity continuity when a motion is "
    "replanned because a part was placed or removed mid-travel",
    "finger data formats (an FMF frame is one float32, the force on that finger; no WSG-DSA); tare has "
    "no effect on readings",
    "web-interface settings beyond the constructor parameters, the system log, anything kept across "
    "power cycles",
    "serial baud rate/framing and CAN bitrate (not enforced); faults.request_close() on UDP/pty/CAN",
    "auto updates faster than the server wakes: at most one update per command per advance (coalesced)",
)

# Where the manuals name no behaviour or status code, the model does this (each marked "sim choice" below).
SIM_CHOICES = (
    "grip while HOLDING whose window lies on the far side of the part (opposite direction): E_CMD_FAILED",
    "grip meeting the part before its window (part wider than nominal + clamping travel): NO PART there",
    "release or pre-position closing onto the part: E_AXIS_BLOCKED at the part",
    "stop (22h) while HOLDING keeps holding; FAST STOP drops the grip (force 0); on 2.2.0 FAST STOP leaves "
    "the grasping state IDLE (2.2.0 has no ERROR state)",
    "finger power control (62h/72h) of a predefined finger (WSG-FMF): E_ACCESS_DENIED; power-on while "
    "powering up: E_ALREADY_RUNNING",
    "non-finite floats, soft limits with minus > plus: E_INVALID_PARAMETER",
    "a server-side TCP drop (faults.request_close()) is an unannounced end of the link: FAST STOP",
    "zero-length motions still answer E_CMD_PENDING first and the final reply on the next advance",
    "auto-update period below the 10 ms minimum (§3.4.1): E_CMD_FORMAT_ERROR, the only refusal listed there",
    "UDP: at most 64 peers are remembered; the one silent longest is forgotten (its auto updates end)",
)

# Change thresholds for "update on changes only": WSG manual 4.0.x §3.4.4–3.4.6.
_CHANGE_THRESHOLD: dict[int, float] = {Cmd.GET_WIDTH: 0.01, Cmd.GET_SPEED: 0.05, Cmd.GET_FORCE: 0.05}
_MIN_PERIOD_MS = 10  # WSG manual 4.0.x §3.4.1: "Minimum value is 10 ms"
_FINGER_POWER_UP_S = 0.5  # WSG manual 4.0.x §3.6.3: "E_SUCCESS after approx. 500 ms"
_EPS = 1e-6


@dataclass
class _Subscription:
    period: float  # simulated seconds
    changes_only: bool
    next_due: float
    last: object


@dataclass
class _Connection:
    connection_oriented: bool
    announced: bool = False  # 07h received: everything else gets E_ACCESS_DENIED
    subscriptions: dict[int, _Subscription] = field(default_factory=dict)


@dataclass
class _Motion:
    kind: str  # "home", "preposition", "grip", "release" or "snap" (no reply: fingers falling through)
    profile: Trapezoid
    target: float  # where the fingers head when nothing is in the way
    contact: float | None  # the part's width when the profile ends on it
    conn: int | None  # who gets the final reply (None: no reply)
    command: int | None
    stop_on_block: bool = True
    grip_width: float = 0.0


@dataclass
class _Finger:
    finger_type: int  # 0 generic, 1 WSG-FMF (WSG manual 4.0.x §3.6.1)
    power_on: bool = True  # "All fingers are powered up on system startup by default" (§3.6.3)
    powering: tuple[float, int, int] | None = None  # (done at, conn, command) while E_CMD_PENDING


class WsgModel:
    """One simulated WSG. Parameters are device units (mm, mm/s, mm/s², N), as a profile gives them."""

    def __init__(
        self,
        *,
        device_type: int = 1,
        hw_revision: int = 1,
        stroke_mm: float = 110.0,
        min_speed: float = 5.0,
        max_speed: float = 420.0,
        min_accel: float = 100.0,
        max_accel: float = 5000.0,
        min_force: float = 5.0,
        max_force: float = 80.0,
        overdrive_force: float | None = None,
        firmware: str = "4.0.1",
        serial: int = 12345,
        part_width_mm: float | None = None,
        clamping_travel_mm: float = 5.0,
        force_fingers: bool = False,
        verify_checksum: bool = True,
        default_accel: float = 1000.0,
        default_force: float | None = None,
        homing_speed: float = 100.0,
        default_homing_direction: int = 1,
        initial_width_mm: float | None = None,
        temperature_c: float = 31.5,
        fast_stop_on_disconnect: bool = True,
    ) -> None:
        if not stroke_mm > 0 or not 0 < min_speed <= max_speed or not 0 < min_accel <= max_accel:
            raise ValueError("stroke, speed and acceleration limits must be positive with min <= max")
        if not 0 <= min_force <= max_force:
            raise ValueError("force limits must satisfy 0 <= min_force <= max_force")
        if default_homing_direction not in (1, 2):
            raise ValueError("default_homing_direction must be 1 (positive) or 2 (negative)")
        if not 0 <= serial <= 0xFFFFFFFF:  # 50h: u32 serial number
            raise ValueError(f"serial must fit a u32, not {serial!r}")
        if part_width_mm is not None and not 0 <= part_width_mm <= stroke_mm:
            raise ValueError(f"part_width_mm must lie within the stroke, not {part_width_mm!r}")
        self.device_type = device_type
        self.hw_revision = hw_revision
        self.stroke = float(stroke_mm)
        self.min_speed, self.max_speed = float(min_speed), float(max_speed)
        self.min_accel, self.max_accel = float(min_accel), float(max_accel)
        self.min_force, self.nominal_force = float(min_force), float(max_force)
        self.overdrive_force = float(overdrive_force if overdrive_force is not None else max_force)
        self.firmware = firmware
        self.firmware_version = FirmwareVersion.parse(firmware)
        self.serial = serial
        self.clamping_travel = float(clamping_travel_mm)
        self.force_fingers = force_fingers
        self.verify_checksum = verify_checksum
        self.homing_speed = float(homing_speed)
        self.default_homing_direction = default_homing_direction
        self.temperature_c = temperature_c
        self.fast_stop_on_disconnect = fast_stop_on_disconnect

        # Session settings (WSG manual §3.3: valid until power-off).
        self.acceleration = self._clamp(default_accel, self.min_accel, self.max_accel)
        self.force_limit = self._clamp(
            default_force if default_force is not None else max_force, self.min_force, self.nominal_force
        )
        self.overdrive = False
        self.soft_limits: tuple[float, float] | None = None
        self.device_tag: str | None = None

        # Device state.
        self.part_width: float | None = part_width_mm
        self.referenced = False
        self.fast_stop = False
        self.axis_stopped = False
        self.target_reached = False
        self.blocked_minus = False
        self.blocked_plus = False
        self.cmd_failure = False
        self.grasping_state = GraspingState.IDLE
        self.holding = False
        self.grip_direction = -1.0
        self.grip_travel_end = 0.0
        self.grip_speed = self.max_speed
        self.clamp_target: float | None = None  # pre-position clamping on a block (clamp on block)
        self.clamp_force = 0.0
        self.stats_total = 0
        self.stats_no_part = 0
        self.stats_lost = 0
        kind = FingerType.WSG_FMF if force_fingers else FingerType.GENERIC
        self.fingers = [_Finger(kind), _Finger(kind)]
        self._x = float(initial_width_mm if initial_width_mm is not None else self.stroke / 2)
        self._motion: _Motion | None = None
        self._now = 0.0

        self._connections: dict[int, _Connection] = {0: _Connection(connection_oriented=True)}
        self._next_conn = 1
        self._out: list[tuple[int, bytes]] = []
        self._handlers: dict[int, Callable[[int, dict, int], None]] = {
            Cmd.LOOP: self._loop,
            Cmd.DISCONNECT: self._disconnect,
            Cmd.HOMING: self._homing,
            Cmd.PREPOSITION: self._preposition,
            Cmd.STOP: self._stop,
            Cmd.FAST_STOP: self._fast_stop,
            Cmd.ACK_FAST_STOP: self._ack_fast_stop,
            Cmd.GRIP: self._grip,
            Cmd.RELEASE: self._release,
            Cmd.SET_ACCELERATION: self._set_acceleration,
            Cmd.GET_ACCELERATION: self._get_acceleration,
            Cmd.SET_FORCE_LIMIT: self._set_force_limit,
            Cmd.GET_FORCE_LIMIT: self._get_force_limit,
            Cmd.SET_SOFT_LIMITS: self._set_soft_limits,
            Cmd.GET_SOFT_LIMITS: self._get_soft_limits,
            Cmd.CLEAR_SOFT_LIMITS: self._clear_soft_limits,
            Cmd.OVERDRIVE: self._overdrive,
            Cmd.TARE: self._tare,
            Cmd.GET_SYSTEM_STATE: self._state_command,
            Cmd.GET_GRASPING_STATE: self._state_command,
            Cmd.GET_GRASPING_STATISTICS: self._statistics,
            Cmd.GET_WIDTH: self._state_command,
            Cmd.GET_SPEED: self._state_command,
            Cmd.GET_FORCE: self._state_command,
            Cmd.GET_TEMPERATURE: self._temperature,
            Cmd.GET_SYSTEM_INFO: self._system_info,
            Cmd.SET_DEVICE_TAG: self._set_device_tag,
            Cmd.GET_DEVICE_TAG: self._get_device_tag,
            Cmd.GET_SYSTEM_LIMITS: self._system_limits,
        }
        for n, base in enumerate((0x60, 0x70)):
            self._handlers[base] = self._finger_handler(n, self._finger_info)
            self._handlers[base + 1] = self._finger_handler(n, self._finger_flags)
            self._handlers[base + 2] = self._finger_handler(n, self._finger_power)
            self._handlers[base + 3] = self._finger_handler(n, self._finger_data)

    # ------------------------------------------------------------------ public API (servers and tests)

    def connect(self, *, connection_oriented: bool = True) -> int:
        """Register a connection (a TCP client, UDP peer, serial line or CAN bus) and return its id."""
        conn = self._next_conn
        self._next_conn += 1
        self._connections[conn] = _Connection(connection_oriented=connection_oriented)
        return conn

    def disconnect(self, conn: int) -> None:
        """Forget a connection without consequences (server shutdown, end of a UDP peer)."""
        self._connections.pop(conn, None)
        self._out = [(c, data) for c, data in self._out if c != conn]
        if self._motion is not None and self._motion.conn == conn:
            self._motion.conn = None

    def connection_lost(self, now: float, conn: int = 0) -> None:
        """The link dropped without a 07h announcement.

        WSG manual 4.0.x §1.4.2: an unannounced TCP close issues a FAST STOP (unless switched off).
        """
        self._advance_to(now)
        c = self._connections.get(conn)
        if c is None:
            return
        if c.connection_oriented and not c.announced and self.fast_stop_on_disconnect:
            self._enter_fast_stop()
        self.disconnect(conn)

    def handle(self, packet: Packet, now: float, conn: int = 0) -> list[bytes]:
        """Replies to send on ``conn`` now: packets due before ``packet`` arrived, then its answers."""
        self._advance_to(now)
        self._dispatch(packet.command, packet.payload, conn)
        return self._take(conn)

    def checksum_failed(self, command: int, now: float, conn: int = 0) -> list[bytes]:
        """A packet arrived whose checksum did not match: answer E_CHECKSUM_ERROR under its id (§1.2.1)."""
        self._advance_to(now)
        self._reply(conn, command, Status.E_CHECKSUM_ERROR)
        return self._take(conn)

    def advance(self, now: float) -> list[bytes]:
        """Everything due by ``now`` for every connection (final async replies, auto updates), in order."""
        return [data for _, data in self.advance_by_connection(now)]

    def advance_by_connection(self, now: float) -> list[tuple[int, bytes]]:
        """Like :meth:`advance`, with the connection each packet goes to."""
        self._advance_to(now)
        out, self._out = self._out, []
        return out

    def next_event_time(self) -> float | None:
        """The simulated time at which :meth:`advance` will next have something to do (None: idle)."""
        times: list[float] = []
        if self._motion is not None:
            times.append(self._motion.profile.t_end)
        times += [f.powering[0] for f in self.fingers if f.powering is not None]
        for c in self._connections.values():
            times += [s.next_due for s in c.subscriptions.values()]
        return min(times) if times else None

    def remove_part(self, now: float | None = None) -> None:
        """Take the part out from between the fingers (tests); a held part becomes PART LOST."""
        self._advance_to(self._now if now is None else now)
        self.part_width = None
        if self.holding:
            # WSG manual 4.0.x §3.4.2: part lost; the fingers fall through the clamping travel.
            self.holding = False
            self.grasping_state = GraspingState.PART_LOST
            self.stats_lost += 1
            self._start_motion("snap", self.grip_travel_end, self.grip_speed, conn=None, command=None)
        elif self.clamp_target is not None:
            # §3.2.2: "If the blocking condition is removed while clamping, the fingers will snap to the
            # target position".
            target, self.clamp_target = self.clamp_target, None
            self.blocked_minus = self.blocked_plus = False
            self._start_motion("snap", target, self.max_speed, conn=None, command=None)
        elif self._motion is not None and self._motion.contact is not None:
            self._replan()

    def place_part(self, width_mm: float, now: float | None = None) -> None:
        """Put a part of ``width_mm`` between the fingers (tests); a motion running into it is replanned."""
        self._advance_to(self._now if now is None else now)
        self.part_width = float(width_mm)
        if self._motion is not None and self._motion.kind != "home":
            self._replan()

    # State readouts (device units), valid at the model's current time.

    @property
    def now(self) -> float:
        return self._now

    @property
    def position(self) -> float:
        """The true finger opening, referenced or not."""
        return self._motion.profile.position(self._now) if self._motion is not None else self._x

    def width(self) -> float:
        # §3.4.4: "If the gripper is not referenced, the command will return an opening width of 0".
        return self.position if self.referenced else 0.0

    def speed(self) -> float:
        return self._motion.profile.velocity(self._now) if self._motion is not None else 0.0

    def force(self) -> float:
        if self.holding:
            return self.force_limit  # brief: force while holding = the force limit
        if self.clamp_target is not None:
            return self.clamp_force
        return 0.0

    def system_flags(self) -> SystemFlags:
        f = SystemFlags(0)
        if self.referenced:
            f |= SystemFlags.SF_REFERENCED
        if self._motion is not None:
            f |= SystemFlags.SF_MOVING
        if self.blocked_minus:
            f |= SystemFlags.SF_BLOCKED_MINUS
        if self.blocked_plus:
            f |= SystemFlags.SF_BLOCKED_PLUS
        if self.soft_limits is not None and self.referenced:
            x = self.position
            if x <= self.soft_limits[0] + _EPS:
                f |= SystemFlags.SF_SOFT_LIMIT_MINUS
            if x >= self.soft_limits[1] - _EPS:
                f |= SystemFlags.SF_SOFT_LIMIT_PLUS
        if self.axis_stopped:
            f |= SystemFlags.SF_AXIS_STOPPED
        if self.target_reached:
            f |= SystemFlags.SF_TARGET_POS_REACHED
        if self.overdrive:
            f |= SystemFlags.SF_OVERDRIVE_MODE
        if self.force_fingers:
            f |= SystemFlags.SF_FORCECNTL_MODE
        if self.fast_stop:
            f |= SystemFlags.SF_FAST_STOP
        if self.cmd_failure:
            f |= SystemFlags.SF_CMD_FAILURE
        return f

    # ------------------------------------------------------------------ plumbing

    @staticmethod
    def _clamp(value: float, lo: float, hi: float) -> float:
        return min(max(float(value), lo), hi)

    def _take(self, conn: int) -> list[bytes]:
        mine = [data for c, data in self._out if c == conn]
        self._out = [(c, data) for c, data in self._out if c != conn]
        return mine

    def _send(self, conn: int | None, command: int, status: int, **fields: object) -> None:
        if conn is None or conn not in self._connections:
            return
        self._out.append((conn, encode_packet(command, encode_reply(command, status, **fields))))

    def _reply(self, conn: int, command: int, status: int, **fields: object) -> None:
        """A command's immediate reply; also keeps SF_CMD_FAILURE ("the last command returned an error")."""
        if status != Status.E_CMD_PENDING:
            self.cmd_failure = status != Status.E_SUCCESS
        self._send(conn, command, status, **fields)

    def _dispatch(self, command: int, payload: bytes, conn: int) -> None:
        c = self._connections[conn]
        if c.announced:
            # §3.1.2: after 07h every further command returns E_ACCESS_DENIED until reconnect.
            self._reply(conn, command, Status.E_ACCESS_DENIED)
            return
        spec = COMMANDS.get(command)
        handler = self._handlers.get(command)
        if spec is None or handler is None or not available(command, self.firmware_version):
            # docs/protocols.md §1: firmware 2.2.0 has no 46h and no 60h–73h -> E_CMD_UNKNOWN.
            self._reply(conn, command, Status.E_CMD_UNKNOWN)
            return
        try:
            fields = decode_request(command, payload)
        except ProtocolError as exc:
            self._reply(conn, command, int(getattr(exc, "status", Status.E_CMD_FORMAT_ERROR)))
            return
        handler(conn, fields, command)

    def _advance_to(self, now: float) -> None:
        now = max(now, self._now)
        m = self._motion
        if m is not None and m.profile.t_end <= now:
            self._now = m.profile.t_end
            self._finish_motion(m)
        for finger in self.fingers:
            if finger.powering is not None and finger.powering[0] <= now:
                _, conn, command = finger.powering
                finger.powering = None
                finger.power_on = True
                self._send(conn, command, Status.E_SUCCESS)
        self._now = now
        for conn, c in list(self._connections.items()):
            for command, sub in c.subscriptions.items():
                if sub.next_due > now + _EPS:
                    continue
                value = self._state_value(command)
                if not sub.changes_only or self._changed(command, sub.last, value):
                    sub.last = value
                    self._send(conn, command, Status.E_SUCCESS, **self._state_fields(command, value))
                # §3.4.1: the period is kept even on changes only; falling behind coalesces updates.
                sub.next_due += sub.period
                if sub.next_due <= now:
                    sub.next_due = now + sub.period

    # ------------------------------------------------------------------ motion

    def _obstacle(self, start: float, target: float) -> float | None:
        """The part's width if a closing travel from ``start`` to ``target`` meets it (external part)."""
        p = self.part_width
        if p is not None and target < start and target < p <= start + _EPS:
            return p
        return None

    def _start_motion(
        self,
        kind: str,
        target: float,
        speed: float,
        *,
        conn: int | None,
        command: int | None,
        stop_on_block: bool = True,
        grip_width: float = 0.0,
    ) -> None:
        start = self.position
        target = self._clamp(target, 0.0, self.stroke)
        contact = None if kind in ("home", "snap") else self._obstacle(start, target)
        end = target if contact is None else contact
        accel = self.acceleration
        profile = Trapezoid(self._now, start, end, speed, accel)
        # Even a zero-length motion ends in advance(): the final reply always follows E_CMD_PENDING (§1.3).
        self._motion = _Motion(kind, profile, target, contact, conn, command, stop_on_block, grip_width)

    def _replan(self) -> None:
        """Restart the current motion from where the fingers are, seeing the part as it is now."""
        m = self._motion
        assert m is not None
        self._x = self.position
        self._start_motion(
            m.kind,
            m.target,
            m.profile.speed,
            conn=m.conn,
            command=m.command,
            stop_on_block=m.stop_on_block,
            grip_width=m.grip_width,
        )

    def _halt(self) -> _Motion | None:
        """Stop the fingers where they are now; returns the interrupted motion."""
        m = self._motion
        if m is not None:
            self._x = m.profile.position(self._now)
            self._motion = None
        return m

    def _abort_motion(self) -> None:
        m = self._halt()
        if m is not None and m.command is not None:
            self._send(m.conn, m.command, Status.E_CMD_ABORTED)

    def _finish_motion(self, m: _Motion) -> None:
        self._x = m.profile.end
        self._motion = None
        status = Status.E_SUCCESS
        if m.kind == "home":
            self.referenced = True
            self.grasping_state = GraspingState.IDLE
            self.target_reached = True
        elif m.kind == "grip":
            self.stats_total += 1
            w, c = m.grip_width, self.clamping_travel
            if m.contact is not None and w - c - _EPS <= m.contact <= w + c + _EPS:
                self.holding = True
                self.grasping_state = GraspingState.HOLDING
            else:
                self.stats_no_part += 1
                self.grasping_state = GraspingState.NO_PART
                status = Status.E_CMD_FAILED
        elif m.kind in ("preposition", "release"):
            self.grasping_state = GraspingState.IDLE
            if m.contact is not None:
                # §3.2.2: a block returns E_AXIS_BLOCKED; clamp on block keeps pushing with limited force.
                status = Status.E_AXIS_BLOCKED
                self.blocked_minus = True
                if not m.stop_on_block:
                    self.clamp_target = m.target
                    major = self.firmware_version.major
                    # 4.0.x §3.2.2: 50 % of the nominal force; 2.2.0 §3.2.2: the set force limit.
                    self.clamp_force = 0.5 * self.nominal_force if major >= 4 else self.force_limit
            else:
                self.target_reached = True
        if m.command is not None:
            if m.conn is not None and m.conn in self._connections:
                self.cmd_failure = status != Status.E_SUCCESS
            self._send(m.conn, m.command, status)

    def _motion_refusal(self, *, needs_reference: bool = True) -> int | None:
        """The immediate error a motion command gets in the current state, or None (WSG manual §3.2)."""
        if self.fast_stop:
            return Status.E_ACCESS_DENIED
        if needs_reference and not self.referenced:
            return Status.E_NOT_INITIALIZED
        if self._motion is not None and self._motion.command is not None:
            # §3.2.1–3.2.7: "Gripper is currently moving. Issue a STOP command, first."
            return Status.E_ALREADY_RUNNING
        return None

    def _outside_soft_limits(self, width: float) -> bool:
        return self.soft_limits is not None and not (
            self.soft_limits[0] - _EPS <= width <= self.soft_limits[1] + _EPS
        )

    def _prepare_motion(self) -> None:
        """What every new motion command clears (Appendix B: SF_AXIS_STOPPED "reset on the next motion")."""
        self._halt()  # a reply-less snap may still be running
        self.axis_stopped = False
        self.target_reached = False
        self.blocked_minus = self.blocked_plus = False
        self.clamp_target = None
        self.holding = False

    @staticmethod
    def _finite(*values: float) -> bool:
        return all(math.isfinite(v) for v in values)

    # ------------------------------------------------------------------ command handlers

    def _loop(self, conn: int, f: dict, cmd: int) -> None:
        self._reply(conn, cmd, Status.E_SUCCESS, **f)

    def _disconnect(self, conn: int, f: dict, cmd: int) -> None:
        c = self._connections[conn]
        if not c.connection_oriented:
            self._reply(conn, cmd, Status.E_NOT_AVAILABLE)  # §3.1.2: only for TCP/IP
            return
        # §3.1.2: "Any finger movement that is executed when the disconnect announcement arrives is aborted".
        self._abort_motion()
        c.subscriptions.clear()
        self._reply(conn, cmd, Status.E_SUCCESS)
        c.announced = True

    def _homing(self, conn: int, f: dict, cmd: int) -> None:
        refusal = self._motion_refusal(needs_reference=False)
        direction = int(f.get("direction", 0))
        if refusal is None and direction not in (0, 1, 2):
            refusal = Status.E_INVALID_PARAMETER
        if refusal is not None:
            self._reply(conn, cmd, refusal)
            return
        self._prepare_motion()
        direction = direction or self.default_homing_direction
        self.grasping_state = GraspingState.POSITIONING
        self._reply(conn, cmd, Status.E_CMD_PENDING)
        # §3.2.1: soft limits are ignored while homing; the end stop becomes the origin.
        target = self.stroke if direction == 1 else 0.0
        self._start_motion("home", target, self.homing_speed, conn=conn, command=cmd)

    def _motion_check(self, width: float, speed: float, target: float) -> int | None:
        """Why a motion to ``target`` must be refused, checked in the order the firmware reports it."""
        refusal = self._motion_refusal()
        if refusal is None and not self._finite(width, speed):
            refusal = Status.E_INVALID_PARAMETER
        if refusal is None and self._outside_soft_limits(target):
            refusal = Status.E_RANGE_ERROR
        return refusal

    def _preposition(self, conn: int, f: dict, cmd: int) -> None:
        width, speed = float(f["width"]), float(f["speed"])
        target = self.position + width if f.get("relative") else width
        refusal = self._motion_check(width, speed, target)
        if refusal is not None:
            self._reply(conn, cmd, refusal)
            return
        self._prepare_motion()
        self.grasping_state = GraspingState.POSITIONING
        self._reply(conn, cmd, Status.E_CMD_PENDING)
        # §3.2.2: positions and speeds beyond the physical limits are clamped.
        self._start_motion(
            "preposition",
            target,
            self._clamp(speed, self.min_speed, self.max_speed),
            conn=conn,
            command=cmd,
            stop_on_block=bool(f.get("stop_on_block", True)),
        )

    def _stop(self, conn: int, f: dict, cmd: int) -> None:
        self._abort_motion()
        self.axis_stopped = True  # §3.2.3: "The command sets the SF_AXIS_STOPPED flag"
        self.clamp_target = None
        self.blocked_minus = self.blocked_plus = False
        moving_states = (GraspingState.GRIPPING, GraspingState.RELEASING, GraspingState.POSITIONING)
        if self.grasping_state in moving_states:
            self.grasping_state = GraspingState.IDLE
        self._reply(conn, cmd, Status.E_SUCCESS)

    def _enter_fast_stop(self) -> None:
        self._abort_motion()
        self.fast_stop = True
        self.holding = False
        self.clamp_target = None
        # 4.0.x §3.4.2: Error (7) "or a FAST STOP was triggered"; 2.2.0 §3.4.2 has no such state (7 is
        # reserved), so a 2.x model goes back to IDLE (sim choice).
        major = self.firmware_version.major
        self.grasping_state = GraspingState.ERROR if major >= 4 else GraspingState.IDLE

    def _fast_stop(self, conn: int, f: dict, cmd: int) -> None:
        self._enter_fast_stop()
        self._reply(conn, cmd, Status.E_SUCCESS)

    def _ack_fast_stop(self, conn: int, f: dict, cmd: int) -> None:
        key = f.get("key", b"")
        if isinstance(key, str):
            key = key.encode("latin-1")
        if key != b"ack":
            self._reply(conn, cmd, Status.E_CMD_FORMAT_ERROR)  # §3.2.5: "Acknowledge key is incorrect"
            return
        self.fast_stop = False
        self._reply(conn, cmd, Status.E_SUCCESS)

    def _grip(self, conn: int, f: dict, cmd: int) -> None:
        width, speed = float(f["width"]), float(f["speed"])
        refusal = self._motion_check(width, speed, width)
        width = self._clamp(width, 0.0, self.stroke) if refusal is None else width
        start = self.position
        direction = -1.0 if width <= start else 1.0
        if self.holding:
            # §3.2.6: re-gripping works in the same direction only; a nominal width whose window lies on
            # the far side of the held part would move the fingers back: "not possible" (code: sim choice).
            direction = self.grip_direction
            if refusal is None and (start - width) * direction > self.clamping_travel + _EPS:
                refusal = Status.E_CMD_FAILED
        if refusal is not None:
            self._reply(conn, cmd, refusal)
            return
        self._prepare_motion()
        speed = self._clamp(speed, self.min_speed, self.max_speed)
        # docs/protocols.md §1: the fingers may travel on by the clamping travel past the nominal width.
        travel_end = self._clamp(width + direction * self.clamping_travel, 0.0, self.stroke)
        if self.soft_limits is not None:
            travel_end = self._clamp(travel_end, *self.soft_limits)
        self.grip_direction, self.grip_travel_end, self.grip_speed = direction, travel_end, speed
        self.grasping_state = GraspingState.GRIPPING
        self._reply(conn, cmd, Status.E_CMD_PENDING)
        self._start_motion("grip", travel_end, speed, conn=conn, command=cmd, grip_width=width)

    def _release(self, conn: int, f: dict, cmd: int) -> None:
        width, speed = float(f["width"]), float(f["speed"])
        refusal = self._motion_check(width, speed, width)
        if refusal is not None:
            self._reply(conn, cmd, refusal)
            return
        self._prepare_motion()
        self.grasping_state = GraspingState.RELEASING
        self._reply(conn, cmd, Status.E_CMD_PENDING)
        self._start_motion(
            "release", width, self._clamp(speed, self.min_speed, self.max_speed), conn=conn, command=cmd
        )

    def _set_acceleration(self, conn: int, f: dict, cmd: int) -> None:
        value = float(f["acceleration"])
        if not self._finite(value):
            self._reply(conn, cmd, Status.E_INVALID_PARAMETER)
            return
        self.acceleration = self._clamp(value, self.min_accel, self.max_accel)  # §3.3.1: limited
        self._reply(conn, cmd, Status.E_SUCCESS)

    def _get_acceleration(self, conn: int, f: dict, cmd: int) -> None:
        self._reply(conn, cmd, Status.E_SUCCESS, acceleration=self.acceleration)

    def _max_force(self) -> float:
        return self.overdrive_force if self.overdrive else self.nominal_force

    def _set_force_limit(self, conn: int, f: dict, cmd: int) -> None:
        value = float(f["force"])
        if not self._finite(value):
            self._reply(conn, cmd, Status.E_INVALID_PARAMETER)
            return
        self.force_limit = self._clamp(value, self.min_force, self._max_force())  # §3.3.3: clamped
        self._reply(conn, cmd, Status.E_SUCCESS)

    def _get_force_limit(self, conn: int, f: dict, cmd: int) -> None:
        self._reply(conn, cmd, Status.E_SUCCESS, force=self.force_limit)

    def _set_soft_limits(self, conn: int, f: dict, cmd: int) -> None:
        minus, plus = float(f["minus"]), float(f["plus"])
        if not self._finite(minus, plus) or minus > plus:
            self._reply(conn, cmd, Status.E_INVALID_PARAMETER)  # sim choice: the manual lists no such case
            return
        self.soft_limits = (minus, plus)
        self._reply(conn, cmd, Status.E_SUCCESS)

    def _get_soft_limits(self, conn: int, f: dict, cmd: int) -> None:
        if self.soft_limits is None:
            self._reply(conn, cmd, Status.E_NOT_AVAILABLE)  # §3.3.6
            return
        self._reply(conn, cmd, Status.E_SUCCESS, minus=self.soft_limits[0], plus=self.soft_limits[1])

    def _clear_soft_limits(self, conn: int, f: dict, cmd: int) -> None:
        self.soft_limits = None
        self._reply(conn, cmd, Status.E_SUCCESS)

    def _overdrive(self, conn: int, f: dict, cmd: int) -> None:
        self.overdrive = bool(f["enable"])
        # §3.3.8: leaving overdrive reduces a force limit beyond the nominal force to the nominal force.
        self.force_limit = min(self.force_limit, self._max_force())
        self._reply(conn, cmd, Status.E_SUCCESS)

    def _tare(self, conn: int, f: dict, cmd: int) -> None:
        if not self.force_fingers:
            self._reply(conn, cmd, Status.E_NOT_AVAILABLE)  # §3.3.9 / docs/protocols.md §1
        elif self.grasping_state == GraspingState.HOLDING:
            self._reply(conn, cmd, Status.E_ACCESS_DENIED)  # §3.3.9: not in force control mode
        else:
            self._reply(conn, cmd, Status.E_SUCCESS)

    def _state_value(self, command: int) -> object:
        if command == Cmd.GET_SYSTEM_STATE:
            return self.system_flags()
        if command == Cmd.GET_GRASPING_STATE:
            return GraspingState(self.grasping_state)
        if command == Cmd.GET_WIDTH:
            return self.width()
        if command == Cmd.GET_SPEED:
            return self.speed()
        return self.force()

    @staticmethod
    def _changed(command: int, last: object, value: object) -> bool:
        threshold = _CHANGE_THRESHOLD.get(command)
        if threshold is None:
            return last != value
        return abs(float(cast(float, value)) - float(cast(float, last))) >= threshold - 1e-9

    @staticmethod
    def _state_fields(command: int, value: object) -> dict[str, object]:
        name = {
            Cmd.GET_SYSTEM_STATE: "state",
            Cmd.GET_GRASPING_STATE: "state",
            Cmd.GET_WIDTH: "width",
            Cmd.GET_SPEED: "speed",
            Cmd.GET_FORCE: "force",
        }[Cmd(command)]
        return {name: value}

    def _state_command(self, conn: int, f: dict, cmd: int) -> None:
        if f.get("auto_update") and int(f.get("period_ms", 0)) < _MIN_PERIOD_MS:
            # WSG manual 4.0.x §3.4.1-3.4.6: "Minimum value is 10 ms"; the only refusal those sections list
            # is E_CMD_FORMAT_ERROR ("Fehler im Befehlsformat", German edition), so a shorter period gets it
            # (sim choice: the manual names no status for this case) and no subscription is changed.
            self._reply(conn, cmd, Status.E_CMD_FORMAT_ERROR)
            return
        value = self._state_value(cmd)
        self._reply(conn, cmd, Status.E_SUCCESS, **self._state_fields(cmd, value))
        subs = self._connections[conn].subscriptions
        if f.get("auto_update"):
            period = max(int(f.get("period_ms", 0)), _MIN_PERIOD_MS) / 1000.0
            subs[cmd] = _Subscription(period, bool(f.get("changes_only")), self._now + period, value)
        else:
            subs.pop(cmd, None)

    def _statistics(self, conn: int, f: dict, cmd: int) -> None:
        self._reply(
            conn,
            cmd,
            Status.E_SUCCESS,
            total=self.stats_total,
            no_part=self.stats_no_part,
            lost_part=self.stats_lost,
        )
        if f.get("reset"):
            self.stats_total = self.stats_no_part = self.stats_lost = 0

    def _temperature(self, conn: int, f: dict, cmd: int) -> None:
        self._reply(conn, cmd, Status.E_SUCCESS, temperature=self.temperature_c)

    def _system_info(self, conn: int, f: dict, cmd: int) -> None:
        self._reply(
            conn,
            cmd,
            Status.E_SUCCESS,
            device_type=self.device_type,
            hw_revision=self.hw_revision,
            firmware=self.firmware_version,
            serial=self.serial,
        )

    def _set_device_tag(self, conn: int, f: dict, cmd: int) -> None:
        raw = f["tag"]  # commands.py decodes it as latin-1 text, a trailing NUL stripped
        tag = raw.encode("latin-1") if isinstance(raw, str) else bytes(raw)
        if len(tag) > 64:
            self._reply(conn, cmd, Status.E_OVERRUN)  # §3.5.2: at most 64 characters
        elif any(b < 0x20 or b > 0x7E for b in tag):
            self._reply(conn, cmd, Status.E_INVALID_PARAMETER)  # §3.5.2: no control characters (ASCII)
        else:
            self.device_tag = tag.decode("ascii") or None
            self._reply(conn, cmd, Status.E_SUCCESS)

    def _get_device_tag(self, conn: int, f: dict, cmd: int) -> None:
        if self.device_tag is None:
            self._reply(conn, cmd, Status.E_NOT_AVAILABLE)  # §3.5.3
        else:
            self._reply(conn, cmd, Status.E_SUCCESS, tag=self.device_tag)

    def _system_limits(self, conn: int, f: dict, cmd: int) -> None:
        self._reply(
            conn,
            cmd,
            Status.E_SUCCESS,
            stroke=self.stroke,
            min_speed=self.min_speed,
            max_speed=self.max_speed,
            min_acceleration=self.min_accel,
            max_acceleration=self.max_accel,
            min_force=self.min_force,
            nominal_force=self.nominal_force,
            overdrive_force=self.overdrive_force,
        )

    # Finger interface (4.x only; WSG manual 4.0.x §3.6).

    def _finger_handler(
        self, n: int, fn: Callable[[int, int, dict, int], None]
    ) -> Callable[[int, dict, int], None]:
        return lambda conn, f, cmd: fn(n, conn, f, cmd)

    def _finger_data_size(self, finger: _Finger) -> int:
        # Sim choice: an FMF data frame is one float32, the force on that finger (N).
        return 4 if finger.finger_type == FingerType.WSG_FMF else 0

    def _finger_info(self, n: int, conn: int, f: dict, cmd: int) -> None:
        finger = self.fingers[n]
        size = self._finger_data_size(finger)
        self._reply(conn, cmd, Status.E_SUCCESS, finger_type=finger.finger_type, data_size=size)

    def _finger_flags(self, n: int, conn: int, f: dict, cmd: int) -> None:
        finger = self.fingers[n]
        flags = FingerFlags.POWER_ON if finger.power_on else FingerFlags(0)
        if finger.finger_type != FingerType.GENERIC:
            # An intelligent finger provides configuration data and talks to the gripper (§3.6.2).
            flags |= FingerFlags.CONFIG_AVAIL | FingerFlags.COMM_OPEN
        self._reply(conn, cmd, Status.E_SUCCESS, flags=flags)

    def _finger_power(self, n: int, conn: int, f: dict, cmd: int) -> None:
        finger = self.fingers[n]
        on = bool(f["power"])
        if finger.finger_type != FingerType.GENERIC:
            # §3.6.3: only generic fingers can be switched; the error code is a sim choice.
            self._reply(conn, cmd, Status.E_ACCESS_DENIED)
        elif not on:
            finger.powering = None
            finger.power_on = False
            self._reply(conn, cmd, Status.E_SUCCESS)  # §3.6.3: disabling is immediate
        elif finger.powering is not None:
            self._reply(conn, cmd, Status.E_ALREADY_RUNNING)
        else:
            self._reply(conn, cmd, Status.E_CMD_PENDING)
            finger.powering = (self._now + _FINGER_POWER_UP_S, conn, cmd)

    def _finger_data(self, n: int, conn: int, f: dict, cmd: int) -> None:
        finger = self.fingers[n]
        if self._finger_data_size(finger) == 0:
            self._reply(conn, cmd, Status.E_NOT_AVAILABLE)  # §3.6.4
            return
        self._reply(conn, cmd, Status.E_SUCCESS, data=struct.pack("<f", self.force() / 2.0))
