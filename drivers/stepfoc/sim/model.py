"""A firmware-faithful model of the MSG gripper on a STEPFOC driver, shared by the CAN and UART simulators.

Pure: no sockets, threads or clocks. Every method takes ``now`` (simulated seconds); servers own the clock.
The behaviour follows docs/protocols.md §2 (CAN, UART, physical facts). Choices the notes leave open, made
here and kept in one place so a test can rely on them:

* Scale: ``ticks_per_mm`` (default 200) encoder ticks per mm of jaw opening, so the 105 mm jaw of an MSG 150
  is 21000 ticks; the speed byte maps linearly to 500..60000 ticks/s (docs/protocols.md §2), i.e. a full
  stroke takes 42 s at speed 0 and 0.35 s at speed 255. There is no acceleration phase.
* Encoder ticks grow towards CLOSED. At power-up the encoder reads 0 wherever the jaws are (``start_mm`` of
  opening), so the calibrated end stops (``min_position`` open, ``max_position`` closed) are arbitrary
  numbers, as on the device.
* Position bytes map to ticks with integer truncation in both directions (docs/protocols.md §2), so a
  commanded 128 reads back as 127 while detection says 3.
* Driver mode, as the firmware keeps it (public STEPFOC firmware ``src/motor_control.cpp``, loop switch on
  ``Controller_mode``): IDLE (0, nothing moves), GRIPPER (11, set by every 5-byte 61 and UART ``Grippos N``),
  CALIBRATE (7, set by 62 / ``Gripcal``). Any active error forces IDLE at the next control step, and command 1
  (clear error), command 12, the end of a calibration and a watchdog trip also leave the driver IDLE: nothing
  moves until a new 5-byte 61 arrives (docs/protocols.md §2, "Firmware behaviour a client must survive").
* Calibration (``Calibrate_gripper``): open at ``calibration_speed`` with ``calibration_current_ma``, pause
  ``calibration_pause_s``, close, then calibrated and IDLE at the closed stop. It writes nothing else: the
  calibrated bit stays set while a calibrated gripper recalibrates, the detection value stays frozen, the
  activate and action bits keep what the last 61 set, and the last 61's bytes survive it. Parts between the
  jaws are ignored during calibration (calibrate with empty jaws).
* "Same command" (``Gripper_mode``): a 5-byte 61 byte-identical to the previous one keeps the at-position
  latch; a latched gripper travels to the target in position mode (at ``POSITION_MODE_TICKS_S``, not at the
  speed setpoint) and reports detection 3 all the way.
* A part (``part_width_mm``, measured as jaw opening) blocks closing for an outside grip (detection 1) or
  opening for an inside grip (``part_grip="inside"``, detection 2). Blocked, the measured current is
  ``blocked_current_ratio`` (95 %) of the limit: negative while closing, positive while opening.
* E-stop: command 0 sets only the DRIVER's e-stop error (identifier error bit, frame 26's estop bit), not
  the 60 frame's estop flag; a 61 with its estop bit sets the gripper's estop error (the 60 flag). Clear error
  (1) clears both, but if the stored 61 still has estop set the error comes back at the next control step
  (docs/protocols.md §2 table, command 1), so "61 with estop 0, then 1" is the order that cannot race.
* The watchdog (15) stores its action byte and never reads it: a trip always sets the timeout error and
  idles the driver.
* Frame 26's byte 1 is the motor driver's own state: its FOC calibration (done at the factory, always set
  here) and its ``Activated`` flag (set only by the UART ``#Activate`` command, never by the gripper), not
  the gripper's bits of frame 60.
* Detection is only recomputed by :meth:`advance` for times after the last new command, so the immediate 60
  reply to a new 61 still carries the previous detection value (docs/protocols.md §2, fine points). In GRIPPER
  mode with the action or activate bit off the firmware reports 0 (its "idle or disabled" branch); in IDLE and
  during calibration the value is frozen.

Not modelled (what the firmware does and this model does not):

* the calibration time-out (150,000 control ticks: calibrated cleared, driver idle) and a calibration that
  stalls on a part between the jaws; the static calibration step counters that an aborted calibration leaves
  half set in the firmware (the next 62 resumes where the aborted one stopped);
* the PID loops, acceleration, the velocity filter and current noise: motion is at constant speed, the current
  is a fixed ``moving_current_ma`` while moving and exactly 0 when the driver is idle;
* a stall below 80 % of the current limit (the firmware reports 0 and keeps pushing; here a part always
  blocks with detection 1/2);
* the vbus, encoder, driver, velocity and current errors and the thermistor check (temperature error only
  when a test sets it);
* the motor modes (data packs 2-5, UART ``#Iq N``, ``#V``, ``#P``…): their frames are ignored and the UART
  names are answered with ``unknown_reply``;
* the firmware's heartbeat goes out with the identifier of command 27 (``Heartbeat_CAN`` in
  ``communication_CAN.cpp``); this model sends command 9 as docs/protocols.md §2 and the vendor library say;
* the watchdog is reset here by every frame addressed to the node, in the firmware only by some commands.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass
from enum import Enum

from ...errors import ProtocolError
from ..can_protocol import (
    COMMANDS,
    CanFrame,
    Cmd,
    Detection,
    DeviceInfo,
    Direction,
    EncoderData,
    ErrorState,
    GripperCommand,
    GripperStatus,
    Watchdog,
    WatchdogAction,
    decode_command,
    decode_frame,
    encode_command,
    encode_frame,
    encode_status,
    pack_id,
    unpack_id,
)

__all__ = ["Mode", "MsgModel", "Phase", "speed_ticks_per_s"]

MIN_SPEED_TICKS = 500.0  # docs/protocols.md §2: speed byte 0..255 -> about 500..60000 ticks/s
MAX_SPEED_TICKS = 60000.0
AT_POSITION_TICKS = 5  # docs/protocols.md §2: "within about 5 encoder ticks of the target it reports 3"
POSITION_MODE_TICKS_S = MAX_SPEED_TICKS  # a latched "same command" travels in position mode (assumed: fast)


def speed_ticks_per_s(speed: int) -> float:
    """Encoder ticks per second for a speed byte (linear map, docs/protocols.md §2)."""
    return MIN_SPEED_TICKS + (MAX_SPEED_TICKS - MIN_SPEED_TICKS) * speed / 255.0


class Phase(Enum):
    """What the motor is doing."""

    IDLE = "idle"  # no torque (power-up, after 12 idle, after calibration, action 0)
    HOLD = "hold"  # gripper mode, at the target or blocked
    MOVING = "moving"
    CAL_OPEN = "calibration: opening"
    CAL_PAUSE = "calibration: pause"
    CAL_CLOSE = "calibration: closing"
    STOPPED = "e-stopped"


_CALIBRATING = (Phase.CAL_OPEN, Phase.CAL_PAUSE, Phase.CAL_CLOSE)


class Mode(Enum):
    """The driver's ``Controller_mode`` values the gripper uses (STEPFOC firmware, motor_control.cpp)."""

    IDLE = 0
    CALIBRATE = 7
    GRIPPER = 11


@dataclass
class _Part:
    width_mm: float
    grip: str  # "outside" blocks closing, "inside" blocks opening


class MsgModel:
    """One MSG gripper node. See the module docstring for the modelling choices."""

    def __init__(
        self,
        *,
        node: int = 0,
        travel_mm: float = 105.0,  # MSG 150 (docs/protocols.md §2 "Physical facts")
        part_width_mm: float | None = None,
        part_grip: str = "outside",
        hardware_version: int = 1,
        batch_date: int = 24,
        software_version: int = 12,
        serial: int = 100_001,
        calibration_current_ma: int = 600,  # docs/protocols.md §2
        calibration_speed: float = 4000.0,  # ticks/s: "slow, taking seconds"
        calibration_pause_s: float = 0.5,
        ticks_per_mm: float = 200.0,
        start_mm: float | None = None,
        temperature_c: int = 31,
        bus_voltage_mv: int = 24_000,
        moving_current_ma: int = 120,
        blocked_current_ratio: float = 0.95,
        gripper_mode: bool = True,
    ) -> None:
        if not 0 <= node <= 15:
            raise ValueError(f"node {node} outside 0..15")
        self.node = node
        self.saved_node = node
        self.travel_mm = float(travel_mm)
        self.ticks_per_mm = float(ticks_per_mm)
        self.hardware_version = hardware_version
        self.batch_date = batch_date
        self.software_version = software_version
        self.serial = serial
        self.calibration_current_ma = calibration_current_ma
        self.calibration_speed = float(calibration_speed)
        self.calibration_pause_s = float(calibration_pause_s)
        self.temperature_c = temperature_c
        self.bus_voltage_mv = bus_voltage_mv
        self.moving_current_ma = moving_current_ma
        self.blocked_current_ratio = blocked_current_ratio
        self.gripper_mode = gripper_mode
        self.part: _Part | None = None
        if part_width_mm is not None:
            self.place_part(part_width_mm, grip=part_grip)
        start = self.travel_mm / 2 if start_mm is None else float(start_mm)
        travel_ticks = round(self.travel_mm * self.ticks_per_mm)
        # physical end stops in encoder ticks; the encoder reads 0 at power-up (ticks grow towards closed)
        self._open_stop = -round((self.travel_mm - start) * self.ticks_per_mm)
        self._closed_stop = self._open_stop + travel_ticks
        self._ticks = 0.0
        self._power_up()

    # ----------------------------------------------------------------------------------- state

    def _power_up(self) -> None:
        self.calibrated = False
        self.min_position = 0  # calibrated open stop (ticks); unknown until calibration
        self.max_position = 0  # calibrated closed stop (ticks)
        self.activated = False
        self.action = False
        self.estop = False  # the estop bit of the stored command
        self.release = False
        self.position_setpoint = 0
        self.speed_setpoint = 0
        self.current_setpoint = 0
        self.detection = Detection.MOVING
        self.estop_error = False  # the gripper's estop error (the 60 frame's flag): a 61 with estop set
        self.driver_estop = False  # the driver's e-stop error (frame 26, error bit): command 0
        self.timeout_error = False
        self.temperature_error = False
        self.driver_activated = False  # frame 26 byte 1: the driver's own flag (UART #Activate)
        self.heartbeat_ms = 0
        self.watchdog = Watchdog(0, WatchdogAction.IDLE)
        self.mode = Mode.IDLE
        self.at_position = False  # the firmware's At_position latch, reset only by a new (different) 61
        self.phase = Phase.IDLE
        self._velocity = 0.0  # ticks/s, signed (closing > 0)
        self._current = 0
        self._last_command: bytes | None = None
        self._command_time = float("-inf")
        self._pause_until = 0.0
        self._arrival_time = 0.0
        self._hold_detection = Detection.AT_POSITION
        self._t: float | None = None
        self._last_rx = 0.0
        self._next_heartbeat: float | None = None
        self._watchdog_fired = False

    @property
    def error_active(self) -> bool:
        """Any active error: the driver then sets the error bit of every identifier it sends."""
        return self.estop_error or self.driver_estop or self.timeout_error or self.temperature_error

    @property
    def calibrating(self) -> bool:
        return self.mode is Mode.CALIBRATE

    @property
    def position(self) -> int:
        """Actual position byte 0 (open) .. 255 (closed), truncated (docs/protocols.md §2)."""
        span = self.max_position - self.min_position
        if span <= 0:
            return 0
        value = (int(self._ticks) - self.min_position) * 255 // span
        return min(255, max(0, value))

    @property
    def ticks(self) -> int:
        return int(self._ticks)

    @property
    def opening_mm(self) -> float:
        """Jaw opening in mm (the physical truth the tests compare against)."""
        return (self._closed_stop - self._ticks) / self.ticks_per_mm

    @property
    def current_ma(self) -> int:
        return self._current

    def target_ticks(self) -> int:
        """Setpoint byte mapped to ticks with integer truncation."""
        return self.min_position + self.position_setpoint * (self.max_position - self.min_position) // 255

    # ----------------------------------------------------------------------------------- parts (tests)

    def place_part(self, width_mm: float, *, grip: str = "outside") -> None:
        if grip not in ("outside", "inside"):
            raise ValueError(f"grip must be 'outside' or 'inside', not {grip!r}")
        if not 0 <= width_mm <= self.travel_mm:
            raise ValueError(f"part width {width_mm} mm outside the jaw travel 0..{self.travel_mm} mm")
        self.part = _Part(float(width_mm), grip)

    def remove_part(self) -> None:
        self.part = None

    def _part_edge(self) -> float | None:
        if self.part is None:
            return None
        return self._closed_stop - self.part.width_mm * self.ticks_per_mm

    # ----------------------------------------------------------------------------------- time

    def advance(self, now: float) -> None:
        """Run the control loop up to ``now`` (simulated seconds)."""
        if self._t is None:
            self._t = now
            self._last_rx = now
        if now < self._t:
            return
        self._check_watchdog(now)
        if self.estop and not self.estop_error and now > self._t:
            self.estop_error = True  # the stored command still carries estop: the error comes back
        if self.error_active and self.mode is not Mode.IDLE:
            self.mode = Mode.IDLE  # firmware: any error disables the driver and sets mode 0
            self._stop(Phase.STOPPED)
        t = self._t
        while t < now:
            t = self._step(t, now)
        self._t = now
        if now > self._command_time:
            self._update_detection()

    def _step(self, t: float, now: float) -> float:
        """Integrate one phase segment from ``t`` towards ``now``; returns the time reached."""
        phase = self.phase
        if phase is Phase.CAL_PAUSE:
            if now < self._pause_until:
                return now
            self._set_motion(Phase.CAL_CLOSE, self.calibration_speed, +1, self.calibration_current_ma)
            return self._pause_until
        if phase is Phase.CAL_OPEN:
            return self._move_to(t, now, float(self._open_stop), self._cal_opened)
        if phase is Phase.CAL_CLOSE:
            return self._move_to(t, now, float(self._closed_stop), self._cal_closed)
        if phase is Phase.MOVING:
            target = float(self.target_ticks())
            stop, blocked = target, False
            edge = self._part_edge()
            if edge is not None and self.part is not None:
                closing_onto = self.part.grip == "outside" and self._ticks <= edge < target
                opening_onto = self.part.grip == "inside" and target < edge <= self._ticks
                if closing_onto or opening_onto:
                    stop, blocked = edge, True
            return self._move_to(t, now, stop, self._blocked if blocked else self._arrived)
        return now

    def _move_to(self, t: float, now: float, stop: float, on_arrival: Callable[[], None]) -> float:
        speed = abs(self._velocity)
        distance = abs(stop - self._ticks)
        if speed <= 0:
            return now
        needed = distance / speed
        if t + needed <= now:
            self._ticks = stop
            self._arrival_time = t + needed
            on_arrival()
            return t + needed
        self._ticks += self._velocity * (now - t)
        return now

    def _set_motion(self, phase: Phase, speed: float, direction: int, limit_ma: int) -> None:
        self.phase = phase
        self._velocity = speed * direction
        self._current = direction * -min(abs(limit_ma), self.moving_current_ma)  # closing draws negative

    def _stop(self, phase: Phase) -> None:
        self.phase = phase
        self._velocity = 0.0
        self._current = 0

    def _cal_opened(self) -> None:
        self._stop(Phase.CAL_PAUSE)
        self._pause_until = self._arrival_time + self.calibration_pause_s

    def _cal_closed(self) -> None:
        # Calibrate_gripper's last step writes the end stops, the calibrated bit and the mode; nothing else
        self.min_position = self._open_stop
        self.max_position = self._closed_stop
        self.calibrated = True
        self.mode = Mode.IDLE
        self._stop(Phase.IDLE)

    def _arrived(self) -> None:
        self._velocity = 0.0
        self._current = 0
        self.phase = Phase.HOLD
        self.at_position = True
        self._hold_detection = Detection.AT_POSITION

    def _blocked(self) -> None:
        closing = self._velocity > 0
        self._velocity = 0.0
        limit = abs(self.current_setpoint)
        magnitude = int(limit * self.blocked_current_ratio)
        self._current = -magnitude if closing else magnitude
        self.phase = Phase.HOLD
        if self.at_position:  # latched: the firmware stays in position mode and keeps reporting 3
            self._hold_detection = Detection.AT_POSITION
        else:
            self._hold_detection = Detection.CLOSING_OBJECT if closing else Detection.OPENING_OBJECT

    def _update_detection(self) -> None:
        if self.mode is not Mode.GRIPPER:
            return  # idle or calibrating: Gripper_mode does not run, the value stays what it was
        if self.phase is Phase.MOVING:
            self.detection = Detection.AT_POSITION if self.at_position else Detection.MOVING
        elif self.phase is Phase.HOLD:
            self.detection = self._hold_detection
        else:
            self.detection = Detection.MOVING  # Gripper_mode's "idle or disabled" branch

    def _check_watchdog(self, now: float) -> None:
        ms = self.watchdog.timeout_ms
        if ms and not self._watchdog_fired and now - self._last_rx > ms / 1000.0:
            # CAN_watchdog: the action byte is stored but never read; the error idles the driver
            self._watchdog_fired = True
            self.timeout_error = True
            self.mode = Mode.IDLE
            self._stop(Phase.STOPPED)

    # ----------------------------------------------------------------------------------- commands

    def _begin(self, now: float) -> None:
        self.advance(now)
        self._last_rx = now
        self._watchdog_fired = False

    def on_command(self, cmd: GripperCommand, now: float) -> bool:
        """A 5-byte 61 command. False when it repeats the previous one byte for byte ("same command").

        Either way the driver goes to gripper mode (aborting a calibration, leaving idle); only a different
        command resets the at-position latch (communication_CAN.cpp, IN_GRIPPER_DATA_PACK; Gripper_mode)."""
        self._begin(now)
        raw = encode_command(cmd)
        same = raw == self._last_command
        self._last_command = raw
        if self.calibrating:
            self._stop(Phase.IDLE)  # a 5-byte 61 aborts calibration (docs/protocols.md §2)
        self.mode = Mode.GRIPPER
        if not same:
            self.at_position = False
            self._command_time = now
        self.position_setpoint = cmd.position
        self.speed_setpoint = cmd.speed
        self.current_setpoint = cmd.current_ma
        self.activated = cmd.activate
        self.action = cmd.action
        self.estop = cmd.estop
        self.release = cmd.release
        if cmd.estop:
            self.estop_error = True
        self._apply(now)
        return not same

    def _apply(self, now: float) -> None:
        """Start or stop motion from the stored setpoints (Gripper_mode, docs/protocols.md §2)."""
        if self.mode is not Mode.GRIPPER:
            return  # idle or calibrating: the setpoints wait for the next 5-byte 61
        if self.error_active:
            self.mode = Mode.IDLE
            self._stop(Phase.STOPPED)
            return
        if not (self.gripper_mode and self.calibrated and self.activated and self.action):
            if self.phase is not Phase.IDLE:
                self._stop(Phase.IDLE)
            return
        target = self.target_ticks()
        if abs(target - self._ticks) <= AT_POSITION_TICKS:
            self._ticks = float(target)
            self._arrived()
            return
        direction = 1 if target > self._ticks else -1
        speed = POSITION_MODE_TICKS_S if self.at_position else speed_ticks_per_s(self.speed_setpoint)
        self._set_motion(Phase.MOVING, speed, direction, self.current_setpoint)

    def start_calibration(self, now: float) -> None:
        """Command 62 / UART Gripcal: only switches the driver to calibration mode (docs/protocols.md §2,
        "Firmware behaviour"): the calibrated bit, the detection value and the last 61 are left alone."""
        self._begin(now)
        if self.error_active:
            return  # the mode is set, but the error puts the driver back to idle before a step runs
        self.mode = Mode.CALIBRATE
        self._set_motion(Phase.CAL_OPEN, self.calibration_speed, -1, self.calibration_current_ma)

    def emergency_stop(self, now: float) -> None:
        """Command 0: the driver's e-stop error only; the 60 frame's estop flag stays as it was."""
        self._begin(now)
        self.driver_estop = True
        self.mode = Mode.IDLE
        self._stop(Phase.STOPPED)

    def clear_error(self, now: float) -> None:
        """Command 1 / UART #Clear: clears every error and idles the driver; nothing moves until a new 5-byte
        61. The estop error returns at the next step if the stored command still has estop."""
        self._begin(now)
        self.estop_error = False
        self.driver_estop = False
        self.timeout_error = False
        self.temperature_error = False
        self.mode = Mode.IDLE
        self._stop(Phase.IDLE)

    def idle(self, now: float) -> None:
        """Command 12 / UART #Idle: driver mode 0; also ends calibration and motion. No bit changes."""
        self._begin(now)
        self.mode = Mode.IDLE
        self._stop(Phase.IDLE)

    def set_node(self, node: int, now: float) -> None:
        """Command 11: takes effect at once; kept over a reset only after save (13)."""
        self._begin(now)
        if 0 <= node <= 15:
            self.node = node

    def save_config(self, now: float) -> None:
        self._begin(now)
        self.saved_node = self.node

    def reset(self, now: float) -> None:
        """Command 14: reboot. Calibration is lost (docs/protocols.md §2); the encoder restarts at 0."""
        self.advance(now)
        shift = self._ticks
        self._open_stop -= round(shift)
        self._closed_stop -= round(shift)
        self._ticks -= round(shift)
        node = self.saved_node
        self._power_up()
        self.node = node
        self._t = now
        self._last_rx = now

    def set_watchdog(self, wd: Watchdog, now: float) -> None:
        self._begin(now)
        self.watchdog = wd

    def set_heartbeat(self, ms: int, now: float) -> None:
        self._begin(now)
        self.heartbeat_ms = ms
        self._next_heartbeat = now + ms / 1000.0 if ms else None

    # UART setters (docs/protocols.md §2 UART): they edit the stored command directly
    def set_position(self, position: int, now: float) -> None:
        """UART Grippos N: set the setpoint, activate, reset the at-position latch and go to gripper mode
        (communication.cpp); the stored 61 bytes are not touched."""
        self._begin(now)
        if self.calibrating:
            self._stop(Phase.IDLE)
        self.position_setpoint = position & 0xFF
        self.activated = True
        self.action = True
        self.at_position = False
        self.mode = Mode.GRIPPER
        self._command_time = now
        self._apply(now)

    def set_speed(self, speed: int, now: float) -> None:
        self._begin(now)
        self.speed_setpoint = speed & 0xFF
        if self.phase is Phase.MOVING:
            self._apply(now)

    def set_current(self, current_ma: int, now: float) -> None:
        self._begin(now)
        self.current_setpoint = int(current_ma)

    def set_activate(self, bit: bool, now: float) -> None:
        self._begin(now)
        self.activated = bool(bit)
        self._apply(now)

    def set_estop(self, bit: bool, now: float) -> None:
        """UART Gripstop N: the stored estop bit; 1 raises the estop error, 0 alone does not clear it."""
        self._begin(now)
        self.estop = bool(bit)
        if bit:
            self.estop_error = True
            self.mode = Mode.IDLE
            self._stop(Phase.STOPPED)

    # ----------------------------------------------------------------------------------- reading

    def status(self, now: float) -> GripperStatus:
        """The 60 frame's content. Does not advance time (the caller decides when the control loop ran)."""
        return GripperStatus(
            position=self.position,
            current_ma=max(-32768, min(32767, self._current)),
            activated=self.activated,
            action=self.action,
            detection=self.detection,
            temperature_error=self.temperature_error,
            timeout_error=self.timeout_error,
            estop_error=self.estop_error,
            calibrated=self.calibrated,
            error_bit=self.error_active,
        )

    def error_state(self) -> ErrorState:
        """Frame 26 (State_of_Errors_CAN): the DRIVER's flags. The estop bit is command 0's error only (a 61
        with estop shows as the error bit alone); byte 1 is the motor's FOC calibration and Activated flag."""
        return ErrorState(
            error=self.error_active,
            temperature=self.temperature_error,
            estop=self.driver_estop,
            calibrated=True,  # the motor's own calibration, done at the factory
            activated=self.driver_activated,
            watchdog=self.timeout_error,
        )

    def device_info(self) -> DeviceInfo:
        return DeviceInfo(self.hardware_version, self.batch_date, self.software_version, self.serial)

    def encoder(self) -> EncoderData:
        return EncoderData(int(self._ticks), int(self._velocity))

    # ----------------------------------------------------------------------------------- CAN frames

    def _out(self, command: int, value: object = None) -> CanFrame:
        return encode_frame(self.node, command, value, error=self.error_active)

    def handle_frame(self, arbitration_id: int, data: bytes, is_remote: bool, now: float) -> list[CanFrame]:
        """One received CAN frame -> the frames the node answers with (often none)."""
        try:
            node, command, _err = unpack_id(arbitration_id)
        except ProtocolError:
            return []
        if node != self.node:
            return []  # frames for other nodes are ignored
        spec = COMMANDS.get(command)
        if spec is None or spec.direction is Direction.NODE_TO_HOST:
            return []
        if command == Cmd.GRIPPER_COMMAND and not is_remote:
            # docs/protocols.md §2: any 61 frame, of any length, is answered with a 60 frame
            if len(data) == 5:
                self.on_command(decode_command(bytes(data)), now)
            else:
                self._begin(now)  # a poll (or a bad length) changes nothing
            return [self._out(Cmd.GRIPPER_STATUS, self.status(now))]
        if spec.direction is Direction.REMOTE:
            if not is_remote:
                return []
            self._begin(now)
            return [self._out(command, self._remote_value(Cmd(command)))]
        if is_remote:
            return []
        try:
            msg = decode_frame(arbitration_id, data, False)
        except ProtocolError:
            return []  # wrong length: the firmware ignores it
        match command:
            case Cmd.ESTOP:
                self.emergency_stop(now)
            case Cmd.CLEAR_ERROR:
                self.clear_error(now)
            case Cmd.SET_CAN_ID:
                self.set_node(msg.value, now)
            case Cmd.IDLE:
                self.idle(now)
            case Cmd.SAVE_CONFIG:
                self.save_config(now)
            case Cmd.RESET:
                self.reset(now)
            case Cmd.WATCHDOG:
                self.set_watchdog(msg.value, now)
            case Cmd.HEARTBEAT_SETUP:
                self.set_heartbeat(msg.value, now)
            case Cmd.GRIPPER_CALIBRATE:
                self.start_calibration(now)
            case _:
                self._begin(now)
        return []

    def _remote_value(self, command: Cmd) -> object:
        match command:
            case Cmd.PING:
                return None
            case Cmd.TEMPERATURE:
                return self.temperature_c
            case Cmd.BUS_VOLTAGE:
                return self.bus_voltage_mv
            case Cmd.DEVICE_INFO:
                return self.device_info()
            case Cmd.ERROR_STATE:
                return self.error_state()
            case Cmd.IQ:
                return max(-32768, min(32767, self._current))
            case Cmd.ENCODER:
                return self.encoder()
        raise AssertionError(command)

    def due_frames(self, now: float) -> list[CanFrame]:
        """Frames the node sends on its own by ``now``: heartbeats (command 9) once set up by 30."""
        if not self.heartbeat_ms or self._next_heartbeat is None:
            return []
        out: list[CanFrame] = []
        period = self.heartbeat_ms / 1000.0
        if now >= self._next_heartbeat:
            out.append(self._out(Cmd.HEARTBEAT))
            # one beat per call: a late server does not burst the missed ones
            self._next_heartbeat = max(self._next_heartbeat + period, now)
        return out

    def next_event(self) -> float | None:
        """Simulated time of the next heartbeat, so a server knows how long it may sleep."""
        return self._next_heartbeat if self.heartbeat_ms else None


def status_bytes(model: MsgModel, now: float) -> bytes:
    """The 60 frame data of ``model`` (a convenience for tests and the UART side)."""
    return encode_status(model.status(now))


def status_id(model: MsgModel) -> int:
    return pack_id(model.node, Cmd.GRIPPER_STATUS, model.error_active)
