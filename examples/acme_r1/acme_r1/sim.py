"""A simulated ACME R1: a pure register model in simulated time, served on TCP by the backend kit.

The model moves at the commanded speed and stops on a part (``part_width_mm``); it is advanced to the
clock's ``now()`` before each answer. The rest is :class:`grippers.kit.SimServer`'s: the scaled clock
(``clock.pause()``/``step()``), the fault hooks (``faults.silent``, ``faults.drop_replies()``,
``faults.stall()``, ``faults.request_close()``...), the server thread (docs/backend-kit.md).
"""

from __future__ import annotations

from grippers.kit import SimServer
from grippers.urls import format_host

from .codec import ERR_ADDRESS, ERR_VALUE, MODEL_R1, Control, Decoder, Frame, FrameError, Reg, Status


class AcmeModel:
    """The registers and the jaws (mm, mm/s); time is passed in, so the model has no clock of its own."""

    def __init__(self, stroke_mm: float, part_width_mm: float | None = None) -> None:
        self.stroke, self.part = stroke_mm, part_width_mm
        self.position = self.target = 0.0  # powers up closed and not homed
        self.speed, self.force, self.force_limit = 50.0, 10.0, 100
        self.status = Status(0)
        self.t = 0.0

    def advance(self, now: float) -> None:
        dt, self.t = max(0.0, now - self.t), now
        if not self.status & Status.MOVING:
            return
        step = self.speed * dt
        goal = self.target
        if self.part is not None and self.position >= self.part > goal:  # closing onto the part
            goal = self.part
        if abs(goal - self.position) <= step:
            self.position = goal
            self.status &= ~Status.MOVING
            self.status |= Status.OBJECT if goal != self.target else Status.AT_TARGET
            if self._homing:
                self.status |= Status.HOMED
                self._homing = False
        else:
            self.position += step if goal > self.position else -step

    _homing = False

    def read(self, addr: int, count: int) -> tuple[int, ...]:
        regs = [round(self.target * 10), round(self.speed), round(self.force), 0, int(self.status)]
        regs += [round(self.position * 10), self.force_limit, MODEL_R1]
        if addr + count > len(regs) or count == 0:
            raise LookupError(addr)
        return tuple(regs[addr : addr + count])

    def write(self, addr: int, values: tuple[int, ...]) -> None:
        for a, v in enumerate(values, addr):
            if a == Reg.TARGET and 0 <= v <= self.stroke * 10:
                self.target = v / 10
            elif a == Reg.SPEED and v > 0:
                self.speed = float(v)
            elif a == Reg.FORCE:
                self.force = float(min(v, self.force_limit))
            elif a == Reg.FORCE_LIMIT and 0 < v <= 1000:
                self.force_limit = v
            elif a == Reg.CONTROL and v in tuple(Control):
                self.control(Control(v))
            else:
                raise ValueError(a)

    def control(self, code: Control) -> None:
        if code is Control.STOP:
            self.status &= ~Status.MOVING
        elif code is Control.RESET:
            self.status &= ~Status.FAULT
        elif code is Control.HOME:
            self.target, self._homing = self.stroke, True
            self.status = (self.status & Status.HOMED) | Status.MOVING
        elif self.status & Status.HOMED:  # GO
            self.status = Status.HOMED | Status.MOVING
        else:
            self.status |= Status.FAULT  # a motion before home(): the device refuses it

    def answer(self, request: Frame, now: float) -> Frame:
        self.advance(now)
        try:
            if request.op == "R":
                return Frame("r", request.addr, self.read(request.addr, request.count or 0))
            self.write(request.addr, request.values)
            return Frame("w", request.addr, count=len(request.values))
        except LookupError:
            return Frame("E", ERR_ADDRESS, count=0)
        except ValueError:
            return Frame("E", ERR_VALUE, count=0)


class AcmeSession:
    """One client's bytes through the codec to the model: a request in, its reply out."""

    def __init__(self, model: AcmeModel) -> None:
        self.model, self.decoder = model, Decoder()

    def feed(self, data: bytes, now: float) -> list[bytes]:
        try:
            frames = self.decoder.feed(data)
        except FrameError:
            return []  # the real device drops a bad frame; the client times out
        return [self.model.answer(frame, now).encode() for frame in frames]


class AcmeServer(SimServer):
    """Serves one model on a TCP port (the kit's server: ``.url``, ``.clock``, ``.faults``, ``close()``)."""

    def __init__(self, model: AcmeModel, host: str = "127.0.0.1", port: int = 0, time_scale: float = 1.0):
        self.model = model
        listen = f"tcp://{format_host(host, port)}"
        super().__init__(listen, lambda: AcmeSession(model), family="acme", time_scale=time_scale)
