"""A simulated Robotiq 2F-85 / 2F-140 / Hand-E: the register model, pure, advanced in simulated time.

Unlike the SDK's fake register model (sdk_cpp/src/fake/register_model.cpp in github.com/robotiq/grippers),
whose activation and motions complete at once, this one follows the manuals and the real device; where each
behaviour and figure comes from (docs/protocols-robotiq.md §3):

- activation: a rising edge of rACT starts a sweep of ``activation_s`` (1 s by default: issue 29's figure,
  not a measured one) reporting gSTA 1 "in progress", then gSTA 3; the fingers close then open across the
  whole stroke (the manual and the SDK docs: "the gripper fully opens and closes"; the order is ours). A part
  between the jaws does not disturb the sweep here (``part_width_mm`` is for the grasps after it); the
  activation fault 0x0D ("verify that no interference ... occurred") is injected with :meth:`inject_fault`.
- rGTO with rACT clear: fault 0x07; rGTO during the activation: fault 0x05, the action runs once activated.
- motion at the speed byte's speed, linear from ``min_speed`` (rSP 0) to ``max_speed`` (rSP 255) as the SDK's
  conversion assumes; the fingers stop at the unit's open and closed counts (gPO 3 and 230 on the SDK's
  2F-85) and gOBJ turns 3 there even when rPR asked beyond (the manual's example: "the fingers have reached
  their software limit").
- a part of ``part_width_mm`` between the jaws stops a closing motion: gOBJ 2; taken away while held, the
  fingers close on to the target and gOBJ turns 3 ("object lost or dropped").
- gCU: 0x10 (160 mA) while moving, the manual's example during a motion; 0 at rest, its example after a grasp.
- faults: injected (:meth:`inject_fault`); major ones (0x0A-0x0F) stop the fingers and are cleared only by
  rACT cleared then set; minor ones (0x08) clear with :meth:`clear_fault`. ``watchdog_s`` (off by default,
  the manual's 1 s when on) reports 0x09 after a silence, until the next command write.
- rATR: the automatic release moves at the minimum speed towards open (rARD 1) or closed (rARD 0), gFLT 0x0B
  meanwhile and 0x0F at the end; a reset is needed afterwards.
- reading the request registers answers zeros, as the SDK's model does.
"""

from __future__ import annotations

from dataclasses import dataclass

from ...modbus import IllegalDataAddress, Request
from ...modbus_model import RegisterModel
from ..registers import (
    COMMAND_ADDRESS,
    DEFAULT_SLAVE,
    MAJOR_FAULTS,
    STATUS_ADDRESS,
    ActivationState,
    Command,
    Fault,
    ObjectDetection,
    Status,
)

BLOCK_SIZE = 8  # registers per block the device answers (bytes 6..15 reserved, read as 0)
MOVING_CURRENT = 0x10  # gCU while moving (manual's example: 160 mA)


@dataclass
class ModelParams:
    """One unit: its stroke, its measured open and closed counts, its speed range (mm/s)."""

    model: str = "2F-85"
    open_width_mm: float = 85.0
    closed_width_mm: float = 0.0
    open_count: int = 3
    closed_count: int = 230
    min_speed_mm_s: float = 20.0
    max_speed_mm_s: float = 150.0
    activation_s: float = 1.0
    slave: int = DEFAULT_SLAVE
    watchdog_s: float | None = None


class RobotiqModel(RegisterModel):
    """The register model, on the kit's :class:`RegisterModel`: :meth:`handle` answers one request at
    simulated time ``now`` as an RTU frame (None: silent), :meth:`answer` as a PDU."""

    def __init__(self, params: ModelParams | None = None, *, part_width_mm: float | None = None) -> None:
        self.p = params or ModelParams()
        self.slave = self.p.slave
        self.part_width_mm = part_width_mm
        self.command = Command()
        self.act = False
        self.sta = ActivationState.RESET
        self.gto = False  # gGTO: the go-to is being carried out
        self.obj = ObjectDetection.MOVING
        self.fault = Fault.NONE.value
        self.position = float(self.p.open_count)
        self.target = self.position
        self.speed_counts_s = 0.0
        self.current = 0
        self._activation_started = 0.0
        self._pending_action = False  # rGTO asked during the activation
        self._releasing = False
        self._now = 0.0
        self._last_request: float | None = None
        self.requests = 0
        self.writes = 0  # requests that wrote the request block

    # -- units ---------------------------------------------------------------------------------------------

    @property
    def counts_per_mm(self) -> float:
        return (self.p.closed_count - self.p.open_count) / (self.p.open_width_mm - self.p.closed_width_mm)

    def count_of(self, width_mm: float) -> float:
        return self.p.open_count + (self.p.open_width_mm - width_mm) * self.counts_per_mm

    def width_mm(self) -> float:
        return self.p.open_width_mm - (self.position - self.p.open_count) / self.counts_per_mm

    def _speed_counts(self, speed_byte: int) -> float:
        p = self.p
        mm_s = p.min_speed_mm_s + (p.max_speed_mm_s - p.min_speed_mm_s) * speed_byte / 255
        return mm_s * self.counts_per_mm

    def _part_count(self) -> float | None:
        if self.part_width_mm is None:
            return None
        count = self.count_of(self.part_width_mm)
        return count if self.p.open_count < count < self.p.closed_count else None

    # -- the device's behaviour ----------------------------------------------------------------------------

    def status(self) -> Status:
        return Status(
            act=self.act,
            gto=self.gto,
            sta=self.sta,
            obj=self.obj if self.gto else ObjectDetection.MOVING,
            fault=self.fault,
            controller_fault=0,
            position_echo=self.command.position,
            position=max(0, min(255, round(self.position))),
            current=self.current,
        )

    def inject_fault(self, code: int) -> None:
        """Raise a fault as the device would; a major one stops the fingers until a reset."""
        self.fault = int(code)
        if code in MAJOR_FAULTS or code == Fault.TEMPERATURE:
            self._halt()

    def clear_fault(self) -> None:
        """A minor fault's cause went away (the gripper cooled down)."""
        if self.fault not in MAJOR_FAULTS:
            self.fault = Fault.NONE

    def _halt(self) -> None:
        self.target = self.position
        self.speed_counts_s = 0.0
        self.current = 0

    def _write(self, cmd: Command, now: float) -> None:
        old = self.command
        self.command = cmd
        if self.fault == Fault.NO_COMMUNICATION:
            self.fault = Fault.NONE
        if not cmd.act:  # reset: clears every fault, stops, forgets the activation
            self.act, self.sta, self.gto = False, ActivationState.RESET, False
            self.obj, self._pending_action, self._releasing = ObjectDetection.MOVING, False, False
            self.fault = Fault.ACTIVATION_BIT if cmd.gto else Fault.NONE
            self._halt()
            return
        if self.fault in MAJOR_FAULTS:
            return  # latched: only a reset (rACT 0, then 1) is heard
        if not old.act or not self.act:  # rising edge of rACT: the activation sweep starts
            self.act, self.sta, self.gto = True, ActivationState.IN_PROGRESS, False
            self._activation_started = now
            self.fault = Fault.NONE
        if cmd.atr:
            self._start_release(cmd)
            return
        if self.sta != ActivationState.COMPLETE:
            if cmd.gto and self.sta == ActivationState.IN_PROGRESS:
                self.fault, self._pending_action = Fault.ACTION_DELAYED, True
            return
        if cmd.gto and self.fault in (Fault.NONE, Fault.ACTION_DELAYED, Fault.ACTIVATION_BIT):
            self.fault = Fault.NONE
            if not self.gto or (cmd.position, cmd.speed, cmd.force) != (old.position, old.speed, old.force):
                self._go(cmd)
        elif not cmd.gto:
            self.gto = False  # stop: the fingers halt where they are
            self._halt()

    def _go(self, cmd: Command) -> None:
        self.gto = True
        lo, hi = self.p.open_count, self.p.closed_count
        self.target = float(min(max(cmd.position, lo), hi))
        self.speed_counts_s = self._speed_counts(cmd.speed)
        self.obj = ObjectDetection.MOVING
        self._settle()

    def _start_release(self, cmd: Command) -> None:
        self._releasing, self.gto = True, False
        self.fault = Fault.AUTO_RELEASE_IN_PROGRESS
        self.sta = ActivationState.RESET
        self.target = float(self.p.open_count if cmd.ard else self.p.closed_count)
        self.speed_counts_s = self._speed_counts(0)

    def _settle(self) -> None:
        """Decide gOBJ and the current when the fingers stand still."""
        part = self._part_count()
        if self.position == self.target:
            self.obj, self.current = ObjectDetection.AT_POSITION, 0
        elif part is not None and self.position == part and self.target > part:
            self.obj, self.current = ObjectDetection.CONTACT_CLOSING, 0
        else:
            self.obj, self.current = ObjectDetection.MOVING, MOVING_CURRENT

    def advance(self, now: float) -> None:
        """Run the device up to simulated time ``now``."""
        dt = max(0.0, now - self._now)
        self._now = max(self._now, now)
        if self.fault in MAJOR_FAULTS and not self._releasing:
            self.current = 0
            return
        if self.act and self.sta == ActivationState.IN_PROGRESS:
            self._activate_step(now)
            return
        if self._releasing:
            self._move(dt, stop_at_part=True)
            part = self._part_count()
            blocked = part is not None and self.position == part and self.target > part
            if self.position == self.target or blocked:
                self._releasing = False
                self.fault = Fault.AUTO_RELEASE_COMPLETE
            return
        if not self.gto or self.fault in MAJOR_FAULTS or self.fault == Fault.TEMPERATURE:
            self.current = 0
            return
        self._move(dt, stop_at_part=True)
        self._settle()

    def _move(self, dt: float, *, stop_at_part: bool) -> None:
        step = self.speed_counts_s * dt
        part = self._part_count() if stop_at_part else None
        if self.target > self.position:
            limit = self.target if part is None or part < self.position else min(self.target, part)
            self.position = min(self.position + step, limit)
        elif self.target < self.position:
            self.position = max(self.position - step, self.target)

    def _activate_step(self, now: float) -> None:
        p = self.p
        frac = (now - self._activation_started) / p.activation_s
        span = p.closed_count - p.open_count
        if frac >= 1.0:
            self.sta = ActivationState.COMPLETE
            self.position = self.target = float(p.open_count)
            self.current = 0
            if self._pending_action:  # the delayed action runs now
                self._pending_action = False
                self.fault = Fault.NONE
                if self.command.gto:
                    self._go(self.command)
            return
        self.current = MOVING_CURRENT
        half = 2 * frac if frac < 0.5 else 2 * (1 - frac)
        self.position = p.open_count + span * half

    # -- Modbus: the registers (the kit's RegisterModel keeps the rules every device keeps) ------------------

    def received(self, request: Request, now: float) -> None:
        """Every request to this gripper: the model runs up to ``now``; a silence past the watchdog before it
        is fault 0x09 until the next command write."""
        self.requests += 1
        self.advance(now)
        w = self.p.watchdog_s
        last = self._last_request
        if w is not None and last is not None and self.act and now - last > w and self.fault == Fault.NONE:
            self.fault = Fault.NO_COMMUNICATION
        self._last_request = now

    def write(self, address: int, values: tuple[int, ...], now: float) -> None:
        start, n = address - COMMAND_ADDRESS, len(values)
        if start < 0 or start + n > BLOCK_SIZE:
            raise IllegalDataAddress()
        self.writes += 1
        regs = list(self.command.registers()) + [0] * BLOCK_SIZE
        regs[start : start + n] = values
        self._write(Command.from_registers(regs[:3]), now)
        self.advance(now)  # "executes one cycle of motion, updates the output, then returns" (FC 23)

    def read(self, function: int, address: int, count: int, now: float) -> list[int]:
        for base, regs in ((STATUS_ADDRESS, self.status().registers()), (COMMAND_ADDRESS, (0, 0, 0))):
            start = address - base
            if start >= 0 and start + count <= BLOCK_SIZE:
                full = list(regs) + [0] * (BLOCK_SIZE - len(regs))
                return full[start : start + count]
        raise IllegalDataAddress()
