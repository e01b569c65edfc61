"""A firmware-faithful model of the MSG gripper on a STEPFOC or Spectral Micro driver, shared by the CAN and
UART simulators.

Pure: no sockets, threads or clocks. Every method takes ``now`` (simulated seconds); servers own the clock.
The behaviour follows docs/protocols.md §2 and the public firmware sources it names (STEPFOC firmware
``src/motor_control.cpp`` ``Gripper_mode`` / ``Calibrate_gripper``, ``src/communication_CAN.cpp``,
``src/communication.cpp``, ``src/common.h``; Spectral Micro firmware, same files). The speed and position maps
come from :mod:`grippers.drivers.stepfoc.speed`, the one model the profiles use too. What it does:

* Encoder ticks grow towards OPEN (``Calibrate_gripper`` opens with a positive velocity and records
  ``max_open_position`` there). At power-up the encoder reads 0 wherever the jaws are (``start_mm``) and the
  stored stops are the firmware's defaults 10329 / -229 until a calibration writes them; the position byte is
  ``mapAndConstrain(ticks, closed, open)`` and a setpoint ``map(setpoint, 0, 255, open, closed)``, both with
  C truncation. Power-up detection value 3 (``common.h``).
* Driver mode (``Controller_mode``): IDLE (0), CALIBRATE (7), GRIPPER (11). Any active error forces IDLE.
* "At position" is ``|target - ticks| < 5``; once set, the latch keeps detection 3 and position mode until a
  5-byte 61 that differs from the node's previous one (from ANY client) resets it at the next control tick. A
  poll (empty 61) that arrives before that tick sets ``Same_command`` again and cancels the reset
  (``communication_CAN.cpp``): the motion then reports 3 throughout.
* Motion: ``map(speed, 0, 255, min_speed, max_speed)`` ticks/s. A motion from rest first spends
  ``START_S`` with the jaws still while the velocity loop asks for its first current (about 360 mA at
  60000 ticks/s, proportional to the velocity setpoint); above 80 % of a low limit that flags an object
  before the jaws moved, as on the device. Blocked by a part the current ramps towards the limit at a rate
  proportional to the velocity setpoint (800 mA in about 2.5 s at speed byte 0), and the object is flagged
  only above 80 % of the limit: late at low speed.
* Current: what the frames carry is measured as the firmware measures it: ADC steps of about 1.6 mA, a fixed
  offset of tens of mA and noise (``current_noise``; deterministic for a ``seed``; on by default, since a
  simulator without noise hides stall bugs). Closing draws negative current, opening positive.
* Calibration (``Calibrate_gripper``), one firmware step at a time with its STATIC state: open at the
  variant's speed byte and current until the current reaches the limit at the stop (``CAL_RAMP_S``; Spectral
  Micro holds it for 3200 more ticks), pause 100 ticks, close the same way, then calibrated and IDLE. Nothing
  else is written: the calibrated bit stays set while a calibrated gripper recalibrates, the detection value
  stays frozen, the activate and action bits and the last 61's bytes survive. A 5-byte 61 aborts it and
  leaves the step flags and the tick counter half set: the next 62 resumes (for example it only closes) and
  the counter keeps adding up, so a later calibration can reach the 150,000-tick time-out (calibrated 0,
  driver idle). Parts between the jaws are ignored during calibration (calibrate with empty jaws).
* Heartbeat (command 9) only after ``heartbeat_ms`` without any frame from the node (``CAN_heartbeat``).
* Watchdog (``CAN_watchdog``): fed only by 61 frames (length 0 or 5), remote requests, data pack 1 (2) at 2, 5
  or 8 bytes and the PD data pack (4) at 8 bytes (``CAN_protocol`` sets ``watchdog_reset`` there and nowhere
  else; data packs 2 and 3, ids 6 and 8, do nothing); it trips again every period while unfed, and at once
  when it is set long after the last feed (command 15 does not restart the timer); its action byte is stored
  and never read. Save (13) stores the node
  id, the watchdog and the heartbeat periods (``EEPROM.cpp``): they survive reset (14).
* E-stop: command 0 sets only the DRIVER's e-stop error; a 61 with its estop bit sets the gripper's estop
  error (the 60 flag) and comes back after clear (1) while the stored 61 still has it.
* Stop (a 61 with action 0): STEPFOC runs velocity mode with setpoint 0, so jaws pressing on a part keep
  their current and the part stays held (detection 1/2 from the "idle or disabled" branch); Spectral Micro
  (``driver``) pulls the bridge's SLEEP and RESET low: no holding force, the part is let go (detection 0,
  current 0).

Not modelled (what the firmware does and this model does not):

* acceleration and the velocity filter beyond ``START_S``; the PID loops (a blocked motion's current ramp is
  a straight line, and a stall below 80 % of the limit, where the firmware keeps pushing and reports 0,
  does not happen: a part always ends in 1 or 2 once the ramp passes 80 %);
* a calibration that stalls on a part between the jaws;
* the vbus, encoder, driver, velocity and current errors and the thermistor check (temperature error only
  when a test sets it);
* the motor modes (data pack 1 and the PD data pack, hall index, gains and limits; UART ``#Iq N``, ``#V``,
  ``#P``...): their frames only feed the watchdog as above, get no ``Data_pack_1_CAN`` reply (3), which the
  firmware always sends, and the UART names are answered with ``unknown_reply``;
* the encoder's absolute angle at power-up (it reads 0 here).
"""

from __future__ import annotations

import random
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
from ..speed import (
    DEFAULT_CLOSED_TICKS,
    DEFAULT_OPEN_TICKS,
    DEFAULT_TICKS_PER_MM,
    STEPFOC,
    DriverVariant,
    arduino_map,
    ticks_per_s,
    variant,
)

__all__ = ["Mode", "MsgModel", "Phase", "speed_ticks_per_s"]

_DATA_PACK_PD = 4  # constants.h IN_DATA_PACK_PD: a motor-mode data pack the codec has no entry for
POSITION_TOLERANCE = 5  # Gripper_mode: "pos_error < POSITION_TOLERANCE"
VELOCITY_CONTACT = 500.0  # ticks/s: VELOCITY_CONTACT_THRESHOLD
CURRENT_CONTACT_RATIO = 0.8  # CURRENT_CONTACT_RATIO
POSITION_MODE_TICKS_S = 60000.0  # a latched "same command" travels in position mode (assumed: fast)
START_S = 0.004  # assumed: jaws still while the velocity loop starts (25 STEPFOC control ticks)
FIRST_CURRENT_MA_PER_TICK_S = 360.0 / 60000.0  # first current request: ~360 mA at 60000 ticks/s
RAMP_MA_S_PER_TICK_S = (800.0 / 2.5) / 500.0  # blocked: 800 mA in ~2.5 s at 500 ticks/s
CAL_RAMP_S = 0.06  # current ramp at a calibration stop, default gains (docs/protocols.md §2)
CAL_STOP_BAND_MA = 30  # Calibrate_gripper: isAroundValue(|Iq|, limit, 30)
ADC_STEP_MA = 1.6  # Get_current_mA: one ADC step
CURRENT_OFFSET_MA = 30.0  # the largest fixed offset drawn for a seed (no offset calibration in the firmware)
CURRENT_NOISE_MA = 5.0  # standard deviation of one reading


def speed_ticks_per_s(speed: int) -> float:
    """Encoder ticks per second for a speed byte on STEPFOC (kept for callers; see speed.ticks_per_s)."""
    return float(ticks_per_s(speed, STEPFOC))


class Phase(Enum):
    """What the motor is doing."""

    IDLE = "idle"  # no torque (power-up, after 12 idle, after calibration, action 0)
    HOLD = "hold"  # gripper mode, at the target
    STARTING = "starting"  # a motion from rest: the first current request, jaws not yet moving
    MOVING = "moving"
    PUSHING = "pushing"  # blocked by a part, the current ramps towards the limit
    RELEASED = "released"  # Spectral Micro stop: bridge off
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
        driver: str | DriverVariant = STEPFOC,
        ticks_per_mm: float = DEFAULT_TICKS_PER_MM,
        start_mm: float | None = None,
        temperature_c: int = 31,
        bus_voltage_mv: int = 24_000,
        moving_current_ma: int = 120,
        blocked_current_ratio: float = 0.95,
        gripper_mode: bool = True,
        current_noise: bool = True,
        seed: int = 0,
    ) -> None:
        if not 0 <= node <= 15:
            raise ValueError(f"node {node} outside 0..15")
        self.driver = variant(driver) if isinstance(driver, str) else driver
        self.node = node
        self.saved_node = node
        self.travel_mm = float(travel_mm)
        self.ticks_per_mm = float(ticks_per_mm)
        self.hardware_version = hardware_version
        self.batch_date = batch_date
        self.software_version = software_version
        self.serial = serial
        self.calibration_current_ma = self.driver.calibration_current_ma
        self.calibration_speed = float(ticks_per_s(self.driver.calibration_speed, self.driver))
        self.calibration_pause_s = self.driver.calibration_pause_ticks / self.driver.loop_hz
        self.temperature_c = temperature_c
        self.bus_voltage_mv = bus_voltage_mv
        self.moving_current_ma = moving_current_ma
        self.blocked_current_ratio = blocked_current_ratio
        self.gripper_mode = gripper_mode
        self.current_noise = current_noise
        self._rng = random.Random(seed)
        self._offset_ma = self._rng.uniform(-CURRENT_OFFSET_MA, CURRENT_OFFSET_MA) if current_noise else 0.0
        self.part: _Part | None = None
        if part_width_mm is not None:
            self.place_part(part_width_mm, grip=part_grip)
        start = self.travel_mm / 2 if start_mm is None else float(start_mm)
        # physical end stops in encoder ticks; the encoder reads 0 at power-up (ticks grow towards OPEN)
        self._closed_stop = -round(start * self.ticks_per_mm)
        self._open_stop = self._closed_stop + round(self.travel_mm * self.ticks_per_mm)
        self._ticks = 0.0
        self.saved_watchdog = Watchdog(0, WatchdogAction.IDLE)
        self.saved_heartbeat_ms = 0
        self._power_up()

    # ----------------------------------------------------------------------------------- state

    def _power_up(self) -> None:
        self.calibrated = False
        self.open_position = DEFAULT_OPEN_TICKS  # Gripper.max_open_position (ticks) until calibrated
        self.closed_position = DEFAULT_CLOSED_TICKS  # Gripper.max_closed_position
        self.activated = False
        self.action = False
        self.estop = False  # the estop bit of the stored command
        self.release = False
        self.position_setpoint = 0
        self.speed_setpoint = 0
        self.current_setpoint = 0
        self.detection = Detection.AT_POSITION  # common.h: object_detection_status = 3
        self.estop_error = False  # the gripper's estop error (the 60 frame's flag): a 61 with estop set
        self.driver_estop = False  # the driver's e-stop error (frame 26, error bit): command 0
        self.timeout_error = False
        self.temperature_error = False
        self.driver_activated = False  # frame 26 byte 1: the driver's own flag (UART #Activate)
        self.heartbeat_ms = self.saved_heartbeat_ms
        self.watchdog = self.saved_watchdog
        self.mode = Mode.IDLE
        self.at_position = False  # the firmware's At_position latch
        self.phase = Phase.IDLE
        self._velocity = 0.0  # ticks/s, signed (opening > 0)
        self._current = 0.0  # true motor current, mA, signed (opening > 0)
        self._ramp = 0.0  # mA/s while pushing
        self._cap = 0.0  # |current| the ramp stops at
        self._goal: float | None = None
        self._on_goal: Callable[[float], None] | None = None
        self._until = 0.0  # end of STARTING, of the pause or of a Spectral confirmation
        self._last_command: bytes | None = None  # Gripper.previousBytes
        self._command_time = float("-inf")
        self._latch_reset_at: float | None = None  # control tick at which Gripper_mode resets At_position
        self._t: float | None = None
        self._last_feed = 0.0
        self._last_tx = 0.0
        # Calibrate_gripper's statics: kept over an aborted calibration, reset at its end and at its time-out
        self._cal_opened = False  # grip_cal_1
        self._cal_paused = False  # grip_delay_1
        self._cal_ticks = 0.0  # tick_gripper_cnt
        self._cal_pause_left = self.calibration_pause_s

    @property
    def error_active(self) -> bool:
        """Any active error: the driver then sets the error bit of every identifier it sends."""
        return self.estop_error or self.driver_estop or self.timeout_error or self.temperature_error

    @property
    def calibrating(self) -> bool:
        return self.mode is Mode.CALIBRATE

    # kept names: the calibrated stops in ticks (min = open, max = closed in the old, closing-positive frame)
    @property
    def min_position(self) -> int:
        return self.open_position

    @property
    def max_position(self) -> int:
        return self.closed_position

    @property
    def position(self) -> int:
        """Actual position byte 0 (open) .. 255 (closed): mapAndConstrain with the stored stops."""
        value = arduino_map(int(self._ticks), self.open_position, self.closed_position, 0, 255)
        return min(255, max(0, value))

    @property
    def ticks(self) -> int:
        return int(self._ticks)

    @property
    def opening_mm(self) -> float:
        """Jaw opening in mm (the physical truth the tests compare against)."""
        return (self._ticks - self._closed_stop) / self.ticks_per_mm

    @property
    def current_ma(self) -> int:
        """The true motor current (mA); frames carry :meth:`measured_current_ma`."""
        return round(self._current)

    def measured_current_ma(self) -> int:
        """One current reading as Get_current_mA gives it: ADC steps, a fixed offset and noise."""
        value = self._current
        if self.current_noise:
            value += self._offset_ma + self._rng.gauss(0.0, CURRENT_NOISE_MA)
            value = round(value / ADC_STEP_MA) * ADC_STEP_MA
        return max(-32768, min(32767, round(value)))

    def target_ticks(self) -> int:
        """Setpoint byte mapped to ticks: map(setpoint, 0, 255, open, closed), C truncation."""
        return arduino_map(self.position_setpoint, 0, 255, self.open_position, self.closed_position)

    # ----------------------------------------------------------------------------------- parts (tests)

    def place_part(self, width_mm: float, *, grip: str = "outside") -> None:
        if grip not in ("outside", "inside"):
            raise ValueError(f"grip must be 'outside' or 'inside', not {grip!r}")
        if not 0 <= width_mm <= self.travel_mm:
            raise ValueError(f"part width {width_mm} mm outside the jaw travel 0..{self.travel_mm} mm")
        self.part = _Part(float(width_mm), grip)

    def remove_part(self) -> None:
        self.part = None
        if self.phase is Phase.PUSHING:  # the jaws were pressing on it: they go on
            self._apply_motion(self._t or 0.0)

    def _part_edge(self) -> float | None:
        if self.part is None:
            return None
        return self._closed_stop + self.part.width_mm * self.ticks_per_mm

    # ----------------------------------------------------------------------------------- time

    def advance(self, now: float) -> None:
        """Run the control loop up to ``now`` (simulated seconds)."""
        if self._t is None:
            self._t = now
            self._last_feed = now
            self._last_tx = now
        if now < self._t:
            return
        self._check_watchdog(now)
        if self.estop and not self.estop_error and now > self._t:
            self.estop_error = True  # the stored command still carries estop: the error comes back
        if self.error_active and self.mode is not Mode.IDLE:
            self.mode = Mode.IDLE  # firmware: any error disables the driver and sets mode 0
            self._stop(Phase.STOPPED)
        if self._latch_reset_at is not None and now >= self._latch_reset_at:
            self._latch_reset_at = None
            # Gripper_mode resets At_position and, in the same tick, sets it again if within tolerance
            self.at_position = self.phase is Phase.HOLD
        t = self._t
        guard = 0
        while t < now and guard < 64:
            t = self._step(t, now)
            guard += 1
        self._t = now
        if now > self._command_time:
            self._update_detection()

    def _step(self, t: float, now: float) -> float:
        """Integrate one phase segment from ``t`` towards ``now``; returns the time reached."""
        if self.mode is Mode.CALIBRATE:
            left = (self.driver.calibration_timeout_ticks - self._cal_ticks) / self.driver.loop_hz
            end = min(now, t + max(0.0, left))
            reached = self._segment(t, end)
            self._cal_ticks += (reached - t) * self.driver.loop_hz
            if (
                self.mode is Mode.CALIBRATE
                and self._cal_ticks >= self.driver.calibration_timeout_ticks - 1e-6
            ):
                self._calibration_timed_out()
            return reached
        return self._segment(t, now)

    def _segment(self, t: float, now: float) -> float:
        phase = self.phase
        if phase in (Phase.STARTING, Phase.CAL_PAUSE) or (phase in _CALIBRATING and self._goal is None):
            if self._ramp > 0:  # a calibration stop: the current grows while the step waits
                sign = 1.0 if self._current >= 0 else -1.0
                span = min(now, self._until) - t
                self._current = sign * min(self._cap, abs(self._current) + self._ramp * max(0.0, span))
            if now < self._until:
                return now
            done_at = self._until
            if phase is Phase.STARTING:
                self._start_travel()
            elif phase is Phase.CAL_PAUSE:
                self._cal_paused = True
                self._begin_cal_close()
            else:
                self._cal_stop_recorded()
            return done_at
        if phase is Phase.PUSHING:
            if self._ramp > 0 and abs(self._current) < self._cap:
                sign = 1.0 if self._current >= 0 else -1.0
                grown = min(self._cap, abs(self._current) + self._ramp * (now - t))
                self._current = sign * grown
            return now
        if phase in (Phase.MOVING, Phase.CAL_OPEN, Phase.CAL_CLOSE) and self._goal is not None:
            speed = abs(self._velocity)
            distance = abs(self._goal - self._ticks)
            needed = distance / speed if speed > 0 else float("inf")
            if t + needed <= now:
                self._ticks = self._goal
                on_goal = self._on_goal
                if on_goal is not None:
                    on_goal(t + needed)
                return t + needed
            self._ticks += self._velocity * (now - t)
            return now
        return now

    # -- motion pieces -------------------------------------------------------------------------------------

    def _stop(self, phase: Phase) -> None:
        self.phase = phase
        self._velocity = 0.0
        self._current = 0.0
        self._goal = None
        self._on_goal = None
        self._ramp = 0.0

    def _travel(
        self, phase: Phase, speed: float, goal: float, limit_ma: float, on_goal: Callable[[float], None]
    ) -> None:
        direction = 1.0 if goal >= self._ticks else -1.0
        self.phase = phase
        self._velocity = direction * speed
        self._current = direction * min(abs(limit_ma), self.moving_current_ma)
        self._goal = goal
        self._on_goal = on_goal
        self._ramp = 0.0

    def _push(self, rate_ma_s: float, limit_ma: float, *, sign: float) -> None:
        """Blocked: the jaws stand still and the current ramps from the running current towards the limit."""
        self._velocity = 0.0
        self._goal = None
        self._on_goal = None
        self._ramp = rate_ma_s
        self._cap = abs(limit_ma) * self.blocked_current_ratio
        self._current = sign * min(abs(self._current) or float(self.moving_current_ma), self._cap)

    # -- gripper mode ---------------------------------------------------------------------------------------

    def _latched(self) -> bool:
        return self.at_position and self._latch_reset_at is None

    def _apply_motion(self, now: float) -> None:
        """Start or stop motion from the stored setpoints (Gripper_mode, docs/protocols.md §2)."""
        if self.mode is not Mode.GRIPPER:
            return  # idle or calibrating: the setpoints wait for the next 5-byte 61
        if self.error_active:
            self.mode = Mode.IDLE
            self._stop(Phase.STOPPED)
            return
        if not (self.gripper_mode and self.calibrated and self.activated and self.action):
            if self.driver.stop_releases:
                self._stop(Phase.RELEASED)  # Spectral Micro: SLEEP and RESET low, the bridge is off
            elif self.phase is Phase.PUSHING:
                # STEPFOC: velocity mode with setpoint 0; the jaws already stand still on the part, so the
                # loop keeps the current it had: the part stays held (and detection keeps saying so)
                self._ramp = 0.0
            elif self.phase is not Phase.IDLE:
                self._stop(Phase.IDLE)
            return
        target = float(self.target_ticks())
        if abs(target - self._ticks) < POSITION_TOLERANCE:
            self._arrived(now)
            return
        if self._latched():
            self._start_travel()  # position mode: no velocity start-up, detection stays 3
            return
        if self.phase in (Phase.MOVING, Phase.STARTING):
            self._start_travel()  # already running: the new setpoint takes over without a new start
            return
        direction = 1.0 if target > self._ticks else -1.0
        v = float(ticks_per_s(self.speed_setpoint, self.driver))
        first = min(abs(self.current_setpoint), FIRST_CURRENT_MA_PER_TICK_S * v)
        self._stop(Phase.STARTING)
        self._current = direction * first
        self._velocity = 0.0
        self._until = now + START_S

    def _start_travel(self) -> None:
        target = float(self.target_ticks())
        speed = (
            POSITION_MODE_TICKS_S if self._latched() else float(ticks_per_s(self.speed_setpoint, self.driver))
        )
        goal, blocked = target, False
        edge = self._part_edge()
        if edge is not None and self.part is not None:
            closing_onto = self.part.grip == "outside" and target < edge <= self._ticks
            opening_onto = self.part.grip == "inside" and self._ticks <= edge < target
            if closing_onto or opening_onto:
                goal, blocked = edge, True
        self._travel(
            Phase.MOVING, speed, goal, self.current_setpoint, self._blocked if blocked else self._arrived
        )

    def _arrived(self, when: float) -> None:
        self._stop(Phase.HOLD)
        self.at_position = True

    def _blocked(self, when: float) -> None:
        # The current pushes towards the commanded target (the firmware's position error), also when the jaws
        # already stood on the part and travelled no distance (their velocity then says nothing of the way).
        sign = 1.0 if float(self.target_ticks()) > self._ticks else -1.0
        v = float(ticks_per_s(self.speed_setpoint, self.driver))
        self.phase = Phase.PUSHING
        self._push(RAMP_MA_S_PER_TICK_S * v, self.current_setpoint, sign=sign)

    def _update_detection(self) -> None:
        if self.mode is not Mode.GRIPPER:
            return  # idle or calibrating: Gripper_mode does not run, the value stays what it was
        limit = CURRENT_CONTACT_RATIO * abs(self.current_setpoint)
        pressing = abs(self._current) > limit and abs(self._velocity) < VELOCITY_CONTACT
        side = Detection.OPENING_OBJECT if self._current > 0 else Detection.CLOSING_OBJECT
        active = self.gripper_mode and self.calibrated and self.activated and self.action
        if not active:
            self.detection = side if pressing else Detection.MOVING  # the "idle or disabled" branch
        elif self.at_position:
            self.detection = Detection.AT_POSITION
        elif self.phase in (Phase.STARTING, Phase.PUSHING):
            self.detection = side if pressing else Detection.MOVING
        else:
            self.detection = Detection.MOVING

    # -- calibration ----------------------------------------------------------------------------------------

    def _resume_calibration(self, now: float) -> None:
        """62: go on from the step the statics say (a fresh calibration starts with opening)."""
        if not self._cal_opened:
            self._travel(
                Phase.CAL_OPEN,
                self.calibration_speed,
                float(self._open_stop),
                self.calibration_current_ma,
                self._cal_at_stop,
            )
        elif not self._cal_paused:
            self._stop(Phase.CAL_PAUSE)
            self._until = now + self._cal_pause_left
        else:
            self._begin_cal_close()

    def _begin_cal_close(self) -> None:
        self._cal_pause_left = self.calibration_pause_s
        self._travel(
            Phase.CAL_CLOSE,
            self.calibration_speed,
            float(self._closed_stop),
            self.calibration_current_ma,
            self._cal_at_stop,
        )

    def _cal_at_stop(self, when: float) -> None:
        """At an end stop: the current ramps up to the limit, then the step records the stop."""
        sign = 1.0 if self._velocity > 0 else -1.0
        limit = float(self.calibration_current_ma)
        self._velocity = 0.0
        self._goal = None
        self._on_goal = None
        start = min(float(self.moving_current_ma), limit)
        self._current = sign * start
        self._cap = limit
        self._ramp = (limit - start) / CAL_RAMP_S
        reach = (limit - CAL_STOP_BAND_MA - start) / self._ramp if self._ramp > 0 else 0.0
        self._until = when + max(0.0, reach) + self.driver.calibration_confirm_ticks / self.driver.loop_hz

    def _cal_stop_recorded(self) -> None:
        if self.phase is Phase.CAL_OPEN:
            self.open_position = int(self._ticks)
            self._cal_opened = True
            self._stop(Phase.CAL_PAUSE)
            self._until = self._until + self.calibration_pause_s
            return
        self.closed_position = int(self._ticks)
        self.calibrated = True  # the last step writes the bit and the mode; nothing else
        self._reset_cal_statics()
        self.mode = Mode.IDLE
        self._stop(Phase.IDLE)

    def _calibration_timed_out(self) -> None:
        self.calibrated = False
        self._reset_cal_statics()
        self.mode = Mode.IDLE
        self._stop(Phase.IDLE)

    def _reset_cal_statics(self) -> None:
        self._cal_opened = self._cal_paused = False
        self._cal_ticks = 0.0
        self._cal_pause_left = self.calibration_pause_s

    def _abort_calibration(self, now: float) -> None:
        """A 5-byte 61 or a UART set leaves calibration mode; the statics stay as they are."""
        if self.phase is Phase.CAL_PAUSE:
            self._cal_pause_left = max(0.0, self._until - now)
        self._stop(Phase.IDLE)

    # -- watchdog --------------------------------------------------------------------------------------------

    def _check_watchdog(self, now: float) -> None:
        ms = self.watchdog.timeout_ms
        if not ms:
            return
        period = ms / 1000.0
        if now - self._last_feed >= period:
            # CAN_watchdog: the action byte is stored but never read; the error idles the driver, and the
            # timer restarts, so it trips again a period later while nothing feeds it
            self.timeout_error = True
            self.mode = Mode.IDLE
            self._stop(Phase.STOPPED)
            self._last_feed += period * int((now - self._last_feed) / period)

    def _feed(self, now: float) -> None:
        self._last_feed = now

    # ----------------------------------------------------------------------------------- commands

    def _begin(self, now: float) -> None:
        self.advance(now)

    def _next_tick(self, now: float) -> float:
        """The control tick after ``now``: when Gripper_mode next runs."""
        tick = self.driver.tick_s
        return (int(now / tick) + 1) * tick

    def on_command(self, cmd: GripperCommand, now: float) -> bool:
        """A 5-byte 61 command. False when it repeats the node's previous one byte for byte ("same command").

        Either way the driver goes to gripper mode (aborting a calibration, leaving idle); only a different
        command resets the at-position latch, at the next control tick (communication_CAN.cpp,
        IN_GRIPPER_DATA_PACK; Gripper_mode)."""
        self._begin(now)
        self._feed(now)
        raw = encode_command(cmd)
        same = raw == self._last_command
        self._last_command = raw
        if self.calibrating:
            self._abort_calibration(now)  # a 5-byte 61 aborts calibration (docs/protocols.md §2)
        self.mode = Mode.GRIPPER
        if not same:
            self._latch_reset_at = self._next_tick(now)
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
        self._apply_motion(now)
        return not same

    def on_poll(self, now: float) -> None:
        """An empty 61: changes nothing, except that it sets ``Same_command`` again. Arriving before the
        control tick that would reset the at-position latch for a new command, it cancels that reset."""
        self._begin(now)
        self._feed(now)
        if self._latch_reset_at is not None and now < self._latch_reset_at:
            self._latch_reset_at = None
            if self.at_position and self.phase in (Phase.STARTING, Phase.MOVING):
                self._start_travel()  # position mode after all: detection 3 throughout

    def start_calibration(self, now: float) -> None:
        """Command 62 / UART Gripcal: only switches the driver to calibration mode (docs/protocols.md §2,
        "Firmware behaviour"): the calibrated bit, the detection value and the last 61 are left alone. The
        step it runs is whatever the calibration's statics say (an aborted one resumes)."""
        self._begin(now)
        if self.error_active:
            return  # the mode is set, but the error puts the driver back to idle before a step runs
        if self.mode is Mode.CALIBRATE:
            return
        self.mode = Mode.CALIBRATE
        self._resume_calibration(now)

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
        if self.calibrating:
            self._abort_calibration(now)
        self.mode = Mode.IDLE
        self._stop(Phase.IDLE)

    def set_node(self, node: int, now: float) -> None:
        """Command 11: takes effect at once; kept over a reset only after save (13)."""
        self._begin(now)
        if 0 <= node <= 15:
            self.node = node

    def save_config(self, now: float) -> None:
        """Command 13 (EEPROM.cpp): stores the node id, the watchdog and the heartbeat periods."""
        self._begin(now)
        self.saved_node = self.node
        self.saved_watchdog = self.watchdog
        self.saved_heartbeat_ms = self.heartbeat_ms

    def reset(self, now: float) -> None:
        """Command 14: reboot. Calibration is lost (docs/protocols.md §2); the encoder restarts at 0; the
        saved node id, watchdog and heartbeat come back."""
        self.advance(now)
        shift = round(self._ticks)
        self._open_stop -= shift
        self._closed_stop -= shift
        self._ticks -= shift
        node = self.saved_node
        self._power_up()
        self.node = node
        self._t = now
        self._last_feed = now
        self._last_tx = now

    def set_watchdog(self, wd: Watchdog, now: float) -> None:
        self._begin(now)
        self.watchdog = wd

    def set_heartbeat(self, ms: int, now: float) -> None:
        self._begin(now)
        self.heartbeat_ms = ms

    # UART setters (docs/protocols.md §2 UART): they edit the stored command directly
    def set_position(self, position: int, now: float) -> None:
        """UART Grippos N: set the setpoint, activate, reset the at-position latch and go to gripper mode
        (communication.cpp); the stored 61 bytes are not touched."""
        self._begin(now)
        if self.calibrating:
            self._abort_calibration(now)
        self.position_setpoint = position & 0xFF
        self.activated = True
        self.action = True
        self.at_position = False
        self._latch_reset_at = None
        self.mode = Mode.GRIPPER
        self._command_time = now
        self._apply_motion(now)

    def set_speed(self, speed: int, now: float) -> None:
        self._begin(now)
        self.speed_setpoint = speed & 0xFF
        if self.phase is Phase.MOVING:
            self._start_travel()

    def set_current(self, current_ma: int, now: float) -> None:
        self._begin(now)
        self.current_setpoint = int(current_ma)

    def set_activate(self, bit: bool, now: float) -> None:
        self._begin(now)
        self.activated = bool(bit)
        self._apply_motion(now)

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
            current_ma=self.measured_current_ma(),
            activated=self.activated,
            action=self.action,
            detection=self.detection,
            temperature_error=self.temperature_error,
            timeout_error=self.timeout_error,
            estop_error=self.estop_error,
            calibrated=self.calibrated,
            error_bit=self.error_active,
        )

    def error_lines(self) -> list[str]:
        """What UART ``#Error`` prints (communication.cpp): the driver's error state, then one line per
        active cause. The motor's own calibration is always done here, so "Not calibrated" never shows."""
        lines = ["In error state!" if self.error_active else "No errors!"]
        if self.temperature_error:
            lines.append("Temp error ")
        if self.driver_estop:
            lines.append("Received ESTOP command")
        if self.timeout_error:
            lines.append("Watchdog error")
        return lines

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
            if command == _DATA_PACK_PD and len(data) == 8 and not is_remote:
                self._begin(now)  # motor mode (not modelled), but it feeds the watchdog (CAN_protocol)
                self._feed(now)
            return []
        if command == Cmd.GRIPPER_COMMAND and not is_remote:
            # docs/protocols.md §2: any 61 frame, of any length, is answered with a 60 frame
            if len(data) == 5:
                self.on_command(decode_command(bytes(data)), now)
            elif len(data) == 0:
                self.on_poll(now)
            else:
                self._begin(now)  # a bad length: Wrong_DL, nothing fed, nothing changed
            return self._sent(now, [self._out(Cmd.GRIPPER_STATUS, self.status(now))])
        if spec.direction is Direction.REMOTE:
            if not is_remote:
                return []
            self._begin(now)
            self._feed(now)  # remote requests feed the watchdog (CAN_watchdog)
            return self._sent(now, [self._out(command, self._remote_value(Cmd(command)))])
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
                if command == Cmd.DATA_PACK_1 and len(data) in (2, 5, 8):
                    self._feed(now)  # data pack 1 feeds the watchdog at its three lengths only (CAN_protocol)
        return []

    def _sent(self, now: float, frames: list[CanFrame]) -> list[CanFrame]:
        if frames:
            self._last_tx = now  # CAN_heartbeat: any frame the node sends restarts the heartbeat timer
        return frames

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
                return self.measured_current_ma()
            case Cmd.ENCODER:
                return self.encoder()
        raise AssertionError(command)

    def due_frames(self, now: float) -> list[CanFrame]:
        """Frames the node sends on its own by ``now``: a heartbeat (command 9) once ``heartbeat_ms`` passed
        without any frame from the node (CAN_heartbeat: every reply restarts the timer)."""
        if not self.heartbeat_ms or now - self._last_tx < self.heartbeat_ms / 1000.0:
            return []
        self._last_tx = now  # one beat per call: a late server does not burst the missed ones
        return [self._out(Cmd.HEARTBEAT)]

    def next_event(self) -> float | None:
        """Simulated time of the next heartbeat, so a server knows how long it may sleep."""
        return self._last_tx + self.heartbeat_ms / 1000.0 if self.heartbeat_ms else None


def status_bytes(model: MsgModel, now: float) -> bytes:
    """The 60 frame data of ``model`` (a convenience for tests and the UART side)."""
    return encode_status(model.status(now))


def status_id(model: MsgModel) -> int:
    return pack_id(model.node, Cmd.GRIPPER_STATUS, model.error_active)
