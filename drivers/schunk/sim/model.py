"""A simulated SCHUNK EGU / EGK / EZU: a pure model of the unit's process data and parameters in simulated
time. Requests in (an instance read or written as bytes), bytes out; time is passed in (``now``, simulated
seconds), so the model has no clock and no I/O and is tested alone. The transports (the web API over HTTP,
Modbus RTU) live beside it and carry the same bytes.

What it does, from SCHUNK's dummy (schunk_gripper_dummy/dummy.py) and driver, with the choices where they
are silent said in docs/protocols-schunk.md: it powers up in error 0xD9 (fast stop) and is not ready until
acknowledged; each command word toggles "command received" (bit 5) and clears the outcome bits of the
previous command; a word with only bit 0 set is no command; bit 0 low is a fast stop; commands other than
acknowledge are ignored (only toggled) while in error; moves run at the target speed (at most the maximum
speed), grips at the target speed or, given 0, at the maximum gripping speed, and stop on a part between the
jaws; release opens by the release delta.
"""

from __future__ import annotations

from dataclasses import dataclass, field

from ..protocol import (
    ERR_FAST_STOP,
    MODBUS_BAUDRATE,
    OUTCOME_BITS,
    PARAMETERS,
    PLC_INPUT,
    PLC_OUTPUT,
    CodecError,
    Control,
    ControlWord,
    Fieldbus,
    Kind,
    ProcessInput,
    Status,
    encode,
    has_gpe,
    padded,
)

GRIP_POSITION_MARGIN_MM = 2.0  # grp_pos_margin (0x0580): the EGU 60 in SCHUNK's dummy configs (EGK 25: 1.0)


@dataclass
class ModuleSpec:
    """One module's parameters, as the unit reports them (mm, mm/s, N)."""

    module_type: int  # 0x0500 (protocol.MODULE_TYPES)
    module_name: str  # e.g. EGU_60_M_B
    min_pos_mm: float
    max_pos_mm: float
    max_phys_stroke_mm: float
    min_vel_mm_s: float
    max_vel_mm_s: float
    max_grp_vel_mm_s: float
    min_grp_force_n: float
    max_grp_force_n: float
    max_allow_force_n: float = 0.0
    release_delta_mm: float = 5.0
    serial: str = "SIM00001"
    firmware: str = "5.3.0.90971"
    serial_num: int = 1
    firmware_num: int = 0x01F7


@dataclass
class _Motion:
    kind: str  # "move", "grip", "release"
    goal_mm: float
    speed_mm_s: float
    target_mm: float  # where the command aimed (a grip's expected position, a move's target)
    outward: bool = False
    gpe: bool = False


@dataclass
class SchunkModel:
    """The unit. ``part_width_mm``: a part between the jaws (None: nothing to grip)."""

    spec: ModuleSpec
    fieldbus: Fieldbus = Fieldbus.ETHERNET_IP
    part_width_mm: float | None = None
    position_mm: float = 0.0
    status: Status = Status.ERROR
    error: int = ERR_FAST_STOP
    output: ControlWord = field(default_factory=ControlWord)
    written: dict[int, bytes] = field(default_factory=dict)  # writable parameters written by a client
    t: float = 0.0
    motion: _Motion | None = None
    speed_mm_s: float = 0.0
    commands: int = 0  # command words taken (tests count them)
    slave_id: int = 12  # Modbus device id (0x11A8), set by the RTU server

    def __post_init__(self) -> None:
        if has_gpe(self.spec.module_name):
            self.status |= Status.GPE  # the units' power-up word in SCHUNK's dummy configs: 0x80000080

    # -- time -------------------------------------------------------------------------------------------

    def advance(self, now: float) -> None:
        dt, self.t = max(0.0, now - self.t), max(self.t, now)
        m = self.motion
        if m is None:
            self.speed_mm_s = 0.0
            return
        goal = m.goal_mm
        blocked_at = self._part_in_the_way(goal)
        stop_at = goal if blocked_at is None else blocked_at
        step = m.speed_mm_s * dt
        if abs(stop_at - self.position_mm) <= step:
            self.position_mm = stop_at
            self._arrived(m, blocked_at is not None)
        else:
            self.position_mm += step if stop_at > self.position_mm else -step
            self.speed_mm_s = m.speed_mm_s

    def _part_in_the_way(self, goal: float) -> float | None:
        part = self.part_width_mm
        if part is None:
            return None
        touching_from_inside = self.position_mm == part and self._outward_grip
        if self.position_mm >= part > goal and not touching_from_inside:  # closing onto it from outside
            return part
        if self.position_mm <= part < goal and self.motion is not None and self.motion.outward:
            return part  # an outward grip opening into a part's inner width
        return None

    def _arrived(self, m: _Motion, at_part: bool) -> None:
        self.motion, self.speed_mm_s = None, 0.0
        if m.kind == "grip":
            if not at_part:
                self.status |= Status.NO_WORKPIECE
                return
            if m.target_mm >= 0 and abs(self.position_mm - m.target_mm) > self._margin():
                self.status |= Status.WRONG_WORKPIECE
                return
            self.status |= Status.GRIPPED | Status.SUCCESS
            if m.gpe:
                self.status |= Status.GPE
            return
        self.status |= Status.SUCCESS
        if not at_part:
            self.status |= Status.REACHED

    # -- faults a test injects ---------------------------------------------------------------------------

    def inject_error(self, code: int) -> None:
        """The unit reports error ``code`` (bit 7, the code at the diagnostics' error byte); motion stops."""
        self.motion, self.speed_mm_s = None, 0.0
        self.status = (self.status | Status.ERROR) & ~Status.READY
        self.error = code

    # -- the parameter interface --------------------------------------------------------------------------

    def read(self, inst: int, now: float) -> bytes | None:
        """The instance's bytes, or None for an instance the unit does not have."""
        self.advance(now)
        if inst == PLC_INPUT:
            return self.process_input().encode(self.fieldbus)
        if inst == PLC_OUTPUT:
            return self.output.encode(self.fieldbus)
        if inst in self.written:
            return self.written[inst]
        value = self._value(inst)
        if value is None:
            return None
        return encode(inst, value, self.fieldbus)

    def write(self, inst: int, data: bytes, now: float) -> bool:
        """Write one instance; False (refused) for an unknown or read-only one or the wrong length."""
        self.advance(now)
        p = PARAMETERS.get(inst)
        if p is None or not p.writable or len(data) != p.size:
            return False
        if inst == PLC_OUTPUT:
            try:
                word = ControlWord.decode(data, self.fieldbus)
            except CodecError:
                return False
            self.command(word)
            return True
        self.written[inst] = padded(inst, data)
        return True

    def process_input(self) -> ProcessInput:
        return ProcessInput(self.status, round(self.position_mm * 1000), self.error, 0, 0)

    def _value(self, inst: int) -> float | int | str | None:
        s = self.spec
        values: dict[int, float | int | str] = {
            0x0118: self.error,
            0x0120: 0,
            0x0128: 0,
            0x0130: "",
            0x03A8: 0.0,
            0x03B0: "00" * 24,
            0x03B8: "00" * 24,
            0x0230: self.position_mm,
            0x0238: self.speed_mm_s,
            0x0380: 0,
            0x0500: s.module_type,
            0x0528: 1.0,
            0x0540: s.release_delta_mm,
            0x0580: GRIP_POSITION_MARGIN_MM,
            0x0588: s.max_phys_stroke_mm,
            0x05A8: 5.0,
            0x0600: s.min_pos_mm,
            0x0608: s.max_pos_mm,
            0x0610: 0.0,
            0x0628: s.min_vel_mm_s,
            0x0630: s.max_vel_mm_s,
            0x0650: s.max_grp_vel_mm_s,
            0x0658: s.min_grp_force_n,
            0x0660: s.max_grp_force_n,
            0x06A8: s.max_allow_force_n,
            # supply and temperature limits and readings: those of the EGU 60 in SCHUNK's dummy configs
            0x0800: 19.2,
            0x0808: 30.0,
            0x0810: 19.2,
            0x0818: 28.8,
            0x0820: -5.0,
            0x0828: 85.0,
            0x0840: 35.0,
            0x0870: 24.0,
            0x0878: 24.0,
            0x0880: 21.6,
            0x0888: 26.4,
            0x0890: 21.6,
            0x0898: 26.4,
            0x08A0: 5.0,
            0x08A8: 75.0,
            0x1000: s.serial.ljust(16),
            0x1008: "SIMULATED".ljust(16),
            0x1020: s.serial_num,
            0x1100: "Jan  1 2025 ",
            0x1108: "00:00:00 ",
            0x1110: s.firmware_num,
            0x1118: s.firmware.ljust(22),
            0x1130: int(self.fieldbus),
            0x1330: True,
            0x1400: int(self.t),
        }
        if self.fieldbus is Fieldbus.MODBUS:  # a Modbus unit has a baud rate and an id, no MAC address
            values.update({0x11A0: MODBUS_BAUDRATE, 0x11A8: self.slave_id})
        else:
            values[0x1138] = "0030" + f"{s.serial_num:08X}"  # an Ethernet unit's MAC, from its serial
        return values.get(inst)

    def _margin(self) -> float:
        """grp_pos_margin (0x0580, mm): how far from a grip's expected position a part may be found."""
        return self._float(0x0580, GRIP_POSITION_MARGIN_MM)

    def _float(self, inst: int, default: float) -> float:
        if inst in self.written and PARAMETERS[inst].kind is Kind.FLOAT:
            from ..protocol import decode

            return float(decode(inst, self.written[inst], self.fieldbus))
        return default

    # -- commands ----------------------------------------------------------------------------------------

    def command(self, word: ControlWord) -> None:
        self.output = word
        if not word.is_command:
            return
        self.commands += 1
        c = word.control
        self.status ^= Status.RECEIVED
        self.status &= ~OUTCOME_BITS
        if c & Control.ACKNOWLEDGE:
            self.status = (self.status | Status.READY) & ~Status.ERROR
            self.error = 0
            return
        if self.status & Status.ERROR:
            return  # ignored while in error, as the dummy does: only the toggle says it was seen
        if not c & Control.FAST_STOP_OFF:
            self.inject_error(ERR_FAST_STOP)
            return
        if c & Control.STOP:
            self.motion, self.speed_mm_s = None, 0.0
            self.status |= Status.SUCCESS | Status.REACHED  # as the dummy reports a controlled stop
            return
        if c & (Control.PREPARE_SHUTDOWN | Control.BRAKE_TEST):
            self.status |= Status.SUCCESS  # the brake test as the dummy answers it: done at once
            return
        lo = self._float(0x0600, self.spec.min_pos_mm)
        hi = self._float(0x0608, self.spec.max_pos_mm)
        gpe = bool(c & Control.GPE) and has_gpe(self.spec.module_name)
        if not gpe:
            self.status &= ~Status.GPE
        if c & Control.RELEASE:
            self.status &= ~(Status.GRIPPED | Status.GPE)
            delta = self._float(0x0540, self.spec.release_delta_mm)
            goal = (
                max(lo, self.position_mm - delta) if self._outward_grip else min(hi, self.position_mm + delta)
            )
            self._start("release", goal, self.spec.max_vel_mm_s, goal)
            return
        if c & (Control.MOVE_ABSOLUTE | Control.MOVE_RELATIVE):
            target = word.position_um / 1000
            if c & Control.MOVE_RELATIVE:
                target += self.position_mm
            speed = word.speed_um_s / 1000
            if speed <= 0 or not lo - 1e-6 <= target <= hi + 1e-6:
                self.status |= Status.NOT_FEASIBLE
                return
            self.status &= ~Status.GRIPPED
            self._start("move", target, min(speed, self.spec.max_vel_mm_s), target)
            return
        if c & (Control.GRIP | Control.GRIP_AT_POSITION):
            speed = word.speed_um_s / 1000 if word.speed_um_s > 0 else self.spec.max_grp_vel_mm_s
            outward = bool(c & Control.OUTWARD)
            self._outward_grip = outward
            expected = word.position_um / 1000 if c & Control.GRIP_AT_POSITION else -1.0
            goal = hi if outward else lo
            if expected >= 0:  # no part within the margin past the expected position: no workpiece there
                goal = min(hi, expected + self._margin()) if outward else max(lo, expected - self._margin())
            self._start("grip", goal, min(speed, self.spec.max_grp_vel_mm_s), expected, outward, gpe)
            return
        self.status |= Status.NOT_FEASIBLE  # a command this model does not take (jogging, brake test)

    _outward_grip = False

    def _start(
        self, kind: str, goal: float, speed: float, target: float, outward: bool = False, gpe: bool = False
    ) -> None:
        self.motion = _Motion(kind, goal, max(speed, 1e-3), target, outward, gpe)
