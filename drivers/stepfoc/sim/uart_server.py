"""The MSG gripper's UART text interface, simulated on a pseudo-terminal.

A client opens the pty's slave path like any serial port (pyserial, minicom, the vendor's tools) and talks the
exact text protocol. The device behaviour lives in :class:`~grippers.drivers.stepfoc.sim.model.MsgModel`
(shared with the CAN simulator); the request parsing and every answer line come from
:mod:`grippers.drivers.stepfoc.uart_protocol`, so this module only maps commands onto the model and moves
bytes.
"""

from __future__ import annotations

import errno
import os
import select
import threading
import time
import tty
from collections import deque
from collections.abc import Sequence
from typing import Any

from ...closing import Closing
from ...simkit import FaultHooks, SimClock, apply_fault, first_half
from ..uart_protocol import (
    COMMANDS,
    MODE_LINES,
    UNKNOWN_COMMAND,
    CommandReceiver,
    GripInfo,
    Request,
    UartInfo,
    atoi,
    encode_lines,
    parser_knows,
    render_gripinfo,
    render_info,
)
from .model import Mode, MsgModel

_TICK_S = 0.02  # wall seconds between control-loop advances while idle
_MAX_OUT = 64 * 1024  # bytes held for a client that does not read; beyond that answers are lost, as on a UART
KEPT_REQUESTS = 256  # the most recent requests kept for tests; a long run must not grow the simulator

# Motor constants the firmware prints in #Info (public firmware, communication.cpp). The notes give no values;
# these are plausible numbers for a small BLDC so the lines are present and parse, nothing depends on them.
SIM_MOTOR_INFO: dict[str, Any] = {
    "phase_direction": 0,
    "phase_order": 0,
    "pole_pairs": 7,
    "resistance": 0.48,
    "inductance": 0.00021,
    "kt": 0.05,
    "kv": 190.0,
}


def _corrupt_text(data: bytes) -> bytes:
    bad = bytearray(data)
    if len(bad) > 1:
        bad[1] ^= 0x01
    return bytes(bad)


class UartSimServer(Closing):
    """One simulated MSG gripper answering on a pty; see :func:`serve_uart`.

    ``lock`` guards the model: hold it when a test changes the model (``place_part``) while the server runs.
    A name the firmware's parser does not know gets no answer at all; ``unknown_reply`` is what a name gets
    that the parser passes on but this simulator does not model (the firmware answers those, see the model's
    "Not modelled" list): ``"Unknown command"`` or None for silence. ``requests`` keeps the last
    :data:`KEPT_REQUESTS` accepted lines, ``request_count`` counts them all.
    """

    def __init__(
        self,
        model: MsgModel,
        *,
        time_scale: float = 1.0,
        clock: SimClock | None = None,
        unknown_reply: str | None = UNKNOWN_COMMAND,
        buffer_size: int = 64,
    ) -> None:
        self.model = model
        self.models = [model]
        self.faults = FaultHooks()
        self.clock = clock or SimClock(time_scale)
        self.unknown_reply = unknown_reply
        self.lock = threading.RLock()
        self.requests: deque[Request] = deque(maxlen=KEPT_REQUESTS)  # the most recent ones, for tests
        self.request_count = 0
        self._receiver = CommandReceiver(buffer_size)
        self._out = bytearray()
        self._delayed: list[tuple[float, bytes]] = []
        self._stop = threading.Event()
        self._closed = False
        self._fds_open = True
        self._master, self._slave = os.openpty()
        # raw: no echo, no CR/LF translation, whatever the client does or does not configure
        tty.setraw(self._slave)
        os.set_blocking(self._master, False)
        self.path = os.ttyname(self._slave)
        self.url = f"stepfoc+serial://{self.path}"
        with self.lock:
            self.model.advance(self.clock.now())
        self._thread = threading.Thread(target=self._run, name=f"msg-uart-sim {self.path}", daemon=True)
        self._thread.start()

    # -- lifecycle ------------------------------------------------------------------------------------------

    def close(self) -> None:
        """Stop the thread and close both pty ends (a connected client sees its port disappear)."""
        if self._closed:
            return
        self._closed = True
        self._stop.set()
        if self._thread is not threading.current_thread():
            self._thread.join(timeout=2.0)
            if self._thread.is_alive():
                # Still running (a starved CPU): it closes the pty itself as it ends (_run). Closed here, the
                # descriptor numbers could go to the next pty this process opens while the old thread still
                # reads and writes them (a busy CI run: a new simulator's client answered by an old model).
                return
        self._close_fds()

    def _close_fds(self) -> None:
        if not self._fds_open:
            return
        self._fds_open = False
        for fd in (self._master, self._slave):
            try:
                os.close(fd)
            except OSError:
                pass

    def __repr__(self) -> str:
        return f"UartSimServer({self.url!r})"

    # -- serving --------------------------------------------------------------------------------------------

    def _run(self) -> None:
        try:
            while not self._stop.is_set():
                if self.faults.close_requested.is_set():
                    self._close_fds()  # the port disappears; close() still joins and is idempotent
                    return
                wlist = [self._master] if self._out else []
                readable, writable, _ = select.select([self._master], wlist, [], self._wait())
                if readable:
                    self._read()
                self._release_delayed()
                if self._out:
                    self._write()
                with self.lock:
                    self.model.advance(self.clock.now())
        except Exception:  # pragma: no cover - a crashing simulator must not hang the tests
            self._close_fds()
            raise
        finally:
            if self._stop.is_set():  # close() may have given up waiting for this thread: its fds, closed last
                self._close_fds()

    def _wait(self) -> float:
        if not self._delayed:
            return _TICK_S
        return max(0.0, min(_TICK_S, min(t for t, _ in self._delayed) - time.monotonic()))

    def _read(self) -> None:
        try:
            data = os.read(self._master, 4096)
        except BlockingIOError:
            return
        except OSError as exc:
            if exc.errno == errno.EIO:  # no client has the slave open right now
                time.sleep(_TICK_S)
                return
            raise
        for item in self._receiver.feed(data):
            if isinstance(item, Request):
                self._handle(item)

    def _write(self) -> None:
        try:
            n = os.write(self._master, self._out)
        except BlockingIOError:
            return
        except OSError:
            self._out.clear()
            return
        del self._out[:n]

    def _release_delayed(self) -> None:
        if not self._delayed:
            return
        now = time.monotonic()
        due = [d for t, d in self._delayed if t <= now]
        self._delayed = [(t, d) for t, d in self._delayed if t > now]
        for data in due:
            self._queue(data)

    def _queue(self, data: bytes) -> None:
        if len(self._out) + len(data) <= _MAX_OUT:
            self._out += data

    def _handle(self, req: Request) -> None:
        with self.lock:
            self.requests.append(req)
            self.request_count += 1
            now = self.clock.now()
            self.model.advance(now)
            lines = self.answer(req, now)
        if lines is not None:
            self._reply(encode_lines(lines))

    def _reply(self, data: bytes) -> None:
        """Send one command's answer through the fault hooks (one fault applies to the whole answer)."""
        if self.faults.silent:
            return
        garbage = self.faults.take_garbage()
        if garbage:
            self._queue(garbage)
        # simkit.apply_fault: the one meaning of each fault; CORRUPT changes the answer's fixed text so the
        # client must not accept it; a text line has no error bit
        out, delay = apply_fault(data, self.faults.take(), corrupt=_corrupt_text, truncate=first_half)
        for answer in out:
            if delay:
                self._delayed.append((time.monotonic() + delay, answer))
            else:
                self._queue(answer)

    # -- the firmware's command dispatch (docs/protocols.md §2 UART; public firmware communication.cpp) ------

    def answer(self, req: Request, now: float) -> list[str] | None:
        """The lines the firmware prints for ``req`` after applying it to the model (None: no answer)."""
        m = self.model
        name = req.name
        if not parser_knows(req):
            return None  # SerialPacketParser drops it: no answer at all (docs/protocols.md §2)
        # the firmware sets only when an argument is present, converting it with atoi
        has_arg = req.argument is not None
        value = atoi(req.argument) if req.argument is not None else 0
        if name == "Gripper":
            if has_arg:
                m.gripper_mode = bool(value)
            return [COMMANDS[name].render(int(m.gripper_mode))]
        if name == "Gripcal":
            m.start_calibration(now)
            return [COMMANDS[name].render()]
        if name == "Grippos":
            if has_arg:
                m.set_position(value, now)
            return [COMMANDS[name].render(m.position)]  # the ACTUAL position, get or set
        if name == "Gripvel":
            if has_arg:
                m.set_speed(value, now)
            return [COMMANDS[name].render(m.speed_setpoint)]
        if name == "Gripcur":
            if has_arg:
                m.set_current(value, now)
            return [COMMANDS[name].render(m.current_setpoint)]
        if name == "Gripact":
            if has_arg:
                m.set_activate(bool(value), now)
            return [COMMANDS[name].render(int(m.activated))]
        if name == "Gripstop":
            if has_arg:
                m.set_estop(bool(value), now)
            return [COMMANDS[name].render(int(m.estop))]
        if name == "Gripinfo":
            return render_gripinfo(self.gripinfo())
        if name == "Info":
            return render_info(self.info())
        if name == "Clear":
            m.clear_error(now)  # firmware: clears every error and puts the driver in idle mode
            return [COMMANDS[name].render()]
        if name == "Idle" and not has_arg:
            m.idle(now)
            return [COMMANDS[name].render()]
        if name == "Error":
            return m.error_lines()  # communication.cpp: the driver's error state, one line per cause
        if name == "Mode":
            line = MODE_LINES.get(m.mode.value if isinstance(m.mode, Mode) else int(m.mode))
            return None if line is None else [line]  # gripper mode (11) prints nothing (communication.cpp)
        return None if self.unknown_reply is None else [self.unknown_reply]

    def gripinfo(self) -> GripInfo:
        m = self.model
        return GripInfo(
            is_gripper=bool(m.gripper_mode),
            calibrated=m.calibrated,
            activated=m.activated,
            position_setpoint=m.position_setpoint,
            speed_setpoint=m.speed_setpoint,
            current_setpoint=m.current_setpoint,
            estop=bool(m.estop),  # the firmware prints the estop bit, not the estop error
            action=m.action,
            detection=m.detection,
            max_open_position=m.open_position,  # the stored end stops in encoder ticks
            max_closed_position=m.closed_position,
        )

    def info(self) -> UartInfo:
        m = self.model
        return UartInfo(
            hardware_version=m.hardware_version,
            batch_date=m.batch_date,
            software_version=m.software_version,
            can_id=m.node,
            calibrated=True,  # the motor's own (FOC) calibration, done at the factory; not the gripper's
            thermistor_enabled=False,  # off by default (docs/protocols.md §2 physical facts)
            vbus_mv=m.bus_voltage_mv,
            **SIM_MOTOR_INFO,
        )


def serve_uart(
    model: MsgModel | Sequence[MsgModel],
    listen: str = "pty",
    *,
    time_scale: float = 1.0,
    unknown_reply: str | None = UNKNOWN_COMMAND,
    clock: SimClock | None = None,
) -> UartSimServer:
    """Serve one MSG gripper's UART on a new pseudo-terminal; ``.url`` is ``stepfoc+serial:///dev/pts/N``.

    A UART is point to point, so exactly one model; ``listen`` must be ``"pty"`` (the only transport).
    """
    if listen != "pty":
        raise ValueError(f"the UART simulator listens on 'pty' only, not {listen!r}")
    if not isinstance(model, MsgModel):
        models = list(model)
        if len(models) != 1:
            raise ValueError(f"a UART serves exactly one gripper, not {len(models)}")
        model = models[0]
    return UartSimServer(model, time_scale=time_scale, clock=clock, unknown_reply=unknown_reply)
