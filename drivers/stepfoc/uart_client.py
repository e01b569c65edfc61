"""A client for the MSG gripper's UART text interface over pyserial (any port or pyserial URL).

The protocol has no framing, no echo and no acknowledgement, and unknown commands are answered with nothing,
so every exchange is: flush what is waiting, send one line, read lines until the expected answer arrives,
throwing away (a bounded number of) lines that are something else, all within a timeout. One lock per
exchange keeps threads from reading each other's answers. The text itself comes from
:mod:`grippers.drivers.stepfoc.uart_protocol`.

A caller that stops waiting from another thread (an asyncio task cancelled: grippers/aio.py) gives its thread
up with :meth:`StepfocUart.abandon`: its exchange ends with GripperTimeout at the next read poll (at most
``_POLL_S``), which frees the port for the next exchange; that one flushes the input first, as after any
timeout, so a late answer of the abandoned one is dropped with it.
"""

from __future__ import annotations

import threading
import time
from collections import deque
from collections.abc import Callable
from typing import TypeVar

import serial

from ..closing import Closing
from ..errors import (
    ConnectionLost,
    GripperError,
    GripperTimeout,
    LimitError,
    NotSupported,
    ProtocolError,
)
from ..serial_ports import open_serial_port
from .dissect import log_uart_line
from .motion import Verdict
from .uart_calibration import UartCalibration
from .uart_protocol import (
    BAUDRATE,
    COMMANDS,
    MAX_CURRENT_MA,
    Answer,
    GripInfo,
    GripInfoAssembler,
    InfoAssembler,
    Line,
    LineSplitter,
    UartInfo,
    format_command,
    is_unknown_command,
    parse_mode,
)

T = TypeVar("T")

URL_SCHEME = "stepfoc+serial://"  # the simulator's family URL; what follows is the pyserial port or URL
_POLL_S = 0.05  # pyserial read timeout; a wait overruns its deadline by at most this much

try:  # POSIX ports report a vanished tty through termios.error, which is not an OSError
    import termios

    _PORT_ERRORS: tuple[type[BaseException], ...] = (serial.SerialException, OSError, termios.error)
except ImportError:  # pragma: no cover - Windows
    _PORT_ERRORS = (serial.SerialException, OSError)


class _Pending:
    """Marker a line handler returns while the answer is not complete yet."""


_PENDING = _Pending()


def _mode_line(line: str) -> int | _Pending:
    mode = parse_mode(line)
    return _PENDING if mode is None else mode


class StepfocUart(Closing):
    """One MSG gripper on a serial port, speaking the STEPFOC UART text protocol.

    ``port`` is anything :func:`serial.serial_for_url` opens (``/dev/ttyACM0``, ``COM3``, ``loop://``,
    ``rfc2217://host:port``) or the simulator's ``stepfoc+serial:///dev/pts/N``. Values are the device's
    own units: position and velocity bytes 0-255 (0 open, 255 closed), current in mA, clamped to
    ``current_limit_ma`` (the profile's limit) before sending, since the firmware does not clamp it.
    """

    def __init__(
        self,
        port: str,
        *,
        baudrate: int = BAUDRATE,
        timeout: float = 0.5,
        device: str | None = None,
        current_limit_ma: int = 1000,
        max_discard: int = 64,
        max_line: int = 256,
    ) -> None:
        if not timeout > 0:
            raise ValueError(f"timeout must be positive, not {timeout!r}")
        if not 0 <= current_limit_ma <= MAX_CURRENT_MA:
            raise LimitError(
                f"current_limit_ma {current_limit_ma} outside 0..{MAX_CURRENT_MA}", device=device or port
            )
        self.port = port[len(URL_SCHEME) :] if port.startswith(URL_SCHEME) else port
        self.device = device or self.port
        self.timeout = float(timeout)
        self.current_limit_ma = int(current_limit_ma)
        self.max_discard = max_discard
        self.discarded = 0  # lines thrown away while resynchronising, over the client's life (diagnostics)
        self._splitter = LineSplitter(max_line)
        self._lines: deque[Line] = deque()
        self._lock = threading.RLock()
        self._abandoned: set[int] = set()  # threads whose caller gave up (abandon(), module docstring)
        self._closed = False
        self._calibration = UartCalibration(self)  # what #Mode showed of a calibration, its verdicts
        self._ser = (
            open_serial_port(  # exclusively (drivers/serial_ports.py: a second process is told "busy")
                self.port,
                device=self.device,
                baudrate=baudrate,
                timeout=min(_POLL_S, self.timeout),
                write_timeout=self.timeout,
            )
        )

    # -- lifecycle ------------------------------------------------------------------------------------------

    @property
    def closed(self) -> bool:
        return self._closed

    @property
    def baudrate(self) -> int:
        """The port's speed (a reconnection opens the port again at it)."""
        return int(self._ser.baudrate)

    def close(self) -> None:
        with self._lock:
            if self._closed:
                return
            self._closed = True
            try:
                self._ser.close()
            except _PORT_ERRORS:
                pass

    def __repr__(self) -> str:
        return f"StepfocUart({self.port!r}{', closed' if self._closed else ''})"

    # -- gripper commands (docs/protocols.md §2 UART) --------------------------------------------------------

    def gripper(self, mode: int | bool | None = None, *, timeout: float | None = None) -> int:
        """Get or set 'am I a gripper' (1 = gripper mode)."""
        return self._value("Gripper", self._bit("Gripper", mode), timeout)

    def calibrate(self, *, wait: bool = False, timeout: float | None = None, poll: float = 0.05) -> None:
        """Start calibration (``#Gripcal``); with ``wait`` poll until it has really ended.

        The calibrated bit stays set while a calibrated gripper recalibrates (docs/protocols.md §2, "Firmware
        behaviour a client must survive"), so the end is read from ``#Mode`` (:meth:`calibration_ended`).
        ``timeout`` bounds the whole wait (default 30 s) when waiting, else the answer line.
        """
        if wait:
            self._calibration.run(30.0 if timeout is None else timeout, poll)
        else:
            self._calibration.send(timeout)

    def mode(self, *, timeout: float | None = None) -> int | None:
        """The driver mode ``#Mode`` prints (0 idle, 7 calibrating, …); None when it prints nothing, which
        the firmware does in gripper mode (11) (communication.cpp)."""
        try:
            return self._exchange("Mode", None, _mode_line, timeout)
        except GripperTimeout:
            return None

    def errors(self, *, timeout: float | None = None) -> list[str]:
        """``#Error`` (communication.cpp): the driver's active error causes as printed (``Temp error``,
        ``Received ESTOP command``, ``Watchdog error``...; ``In error state!`` alone when it names none), or
        [] for ``No errors!``. Its length varies, so ``#Gripper`` is sent behind it to mark the end."""
        lines: list[str] = []
        end = COMMANDS["Gripper"]

        def handle(line: str) -> list[str] | _Pending:
            text = line.strip()
            if end.parse(line) is not None and lines:
                state, causes = lines[0], lines[1:]
                if state == "No errors!":
                    return []
                return causes or [state]
            if text in ("In error state!", "No errors!") or lines:
                lines.append(text)
            return _PENDING

        return self._exchange("Error", None, handle, timeout, extra=format_command("Gripper"))

    def start_calibration(self, *, command: str = "Gripcal") -> None:
        """``#Gripcal`` after ``#Error``: with any driver error the firmware forces mode 0 at its next tick,
        so the calibration would not run while ``#Gripinfo`` showed nothing wrong (docs/protocols.md §2).
        CommandFailed naming the error instead. Resets what :meth:`calibration_verdict` has seen."""
        self._calibration.start(command)

    def calibration_verdict(self, *, command: str = "Gripcal") -> Verdict:
        """RUNNING while ``#Mode`` says calibrating; ENDED once it idles after it was SEEN calibrating, with
        the calibrated bit set and the jaws at the closed stop; RETRY when it idles without having been seen
        running (it never started, or ended between two polls). CommandFailed when it ended any other way
        (aborted by a motion command, an error - named from ``#Error`` - or the calibration time-out)."""
        return self._calibration.verdict(command)

    def calibration_ended(self, *, command: str = "Gripcal") -> bool:
        """True once the calibration ended (see :meth:`calibration_verdict`); CommandFailed for a RETRY."""
        return self._calibration.ended(command)

    def position(self, setpoint: int | None = None, *, timeout: float | None = None) -> int:
        """The ACTUAL position byte; with ``setpoint`` also activates and starts the motion (firmware)."""
        return self._value("Grippos", self._byte("Grippos", setpoint), timeout)

    def velocity(self, v: int | None = None, *, timeout: float | None = None) -> int:
        """Get or set the velocity setpoint byte (0 slowest .. 255 fastest)."""
        return self._value("Gripvel", self._byte("Gripvel", v), timeout)

    def current(self, ma: int | None = None, *, timeout: float | None = None) -> int:
        """Get or set the current setpoint in mA; a set is clamped to ``current_limit_ma`` first."""
        if ma is not None:
            if isinstance(ma, bool) or not isinstance(ma, int):
                raise LimitError(
                    f"current must be an integer mA value, not {ma!r}", device=self.device, command="Gripcur"
                )
            if ma < 0:
                raise LimitError(f"current {ma} mA is negative", device=self.device, command="Gripcur")
            ma = min(ma, self.current_limit_ma)
        return self._value("Gripcur", ma, timeout)

    def activate(self, bit: int | bool | None = None, *, timeout: float | None = None) -> int:
        """Get or set the activation bit."""
        return self._value("Gripact", self._bit("Gripact", bit), timeout)

    def estop(self, bit: int | bool | None = None, *, timeout: float | None = None) -> int:
        """Get or set the estop bit (1 stops the gripper; clearing it needs :meth:`clear_error` as well)."""
        return self._value("Gripstop", self._bit("Gripstop", bit), timeout)

    def clear_error(self, *, timeout: float | None = None) -> None:
        """``#Clear``: clears all errors (also the gripper's estop error) and sets the driver idle."""
        self._exchange("Clear", None, self._single("Clear"), timeout)

    def gripinfo(self, *, timeout: float | None = None) -> GripInfo:
        """The eleven ``#Gripinfo`` lines as one record."""
        asm = GripInfoAssembler()

        def handle(line: str) -> GripInfo | _Pending:
            info = asm.feed(line)
            return _PENDING if info is None else info

        return self._exchange("Gripinfo", None, handle, timeout, discarded=lambda: asm.discarded)

    def info(self, *, timeout: float | None = None) -> UartInfo:
        """``#Info``: versions, CAN id and status lines.

        Its length varies with firmware and state, so ``#Gripper`` (a harmless get) is sent right behind it:
        its answer marks the end of the Info lines without waiting for a quiet gap.
        """
        asm = InfoAssembler()
        end = COMMANDS["Gripper"]

        def handle(line: str) -> UartInfo | _Pending:
            if end.parse(line) is not None and asm.header_complete:
                return asm.finish()
            asm.feed(line)  # a 'Gripper: N' before the Info lines is noise and discarded
            return _PENDING

        sentinel = format_command("Gripper")
        return self._exchange("Info", None, handle, timeout, extra=sentinel, discarded=lambda: asm.discarded)

    def query(self, name: str, value: int | None = None, *, timeout: float | None = None) -> Answer:
        """Any single-line command of the table, raw (for tools); values are checked by the table only."""
        if name not in COMMANDS or COMMANDS[name].lines != 1:
            raise NotSupported(f"not a single-line UART command: {name!r}", device=self.device, command=name)
        return self._exchange(name, value, self._single(name), timeout)

    def command(self, name: str, value: int | None = None, *, timeout: float | None = None) -> str:
        """Any command, known to the table or not (``#Temp``, ``#Vbus``): its first answer line, raw.

        Unknown names are what the firmware ignores or answers with ``Unknown command``: the first gives
        :class:`GripperTimeout`, the second :class:`NotSupported`.
        """
        return self._exchange(name, value, lambda line: line, timeout)

    # -- internals ------------------------------------------------------------------------------------------

    def _byte(self, command: str, value: int | None) -> int | None:
        if value is None:
            return None
        if isinstance(value, bool) or not isinstance(value, int) or not 0 <= value <= 255:
            raise LimitError(f"{value!r} is not a byte 0..255", device=self.device, command=command)
        return value

    def _bit(self, command: str, value: int | bool | None) -> int | None:
        if value is None:
            return None
        if value not in (0, 1) or not isinstance(value, int):
            raise LimitError(f"{value!r} is not a bit 0/1", device=self.device, command=command)
        return int(value)

    def _value(self, command: str, value: int | None, timeout: float | None) -> int:
        answer = self._exchange(command, value, self._single(command), timeout)
        assert answer.value is not None
        return answer.value

    @staticmethod
    def _single(command: str) -> Callable[[str], Answer | _Pending]:
        spec = COMMANDS[command]

        def handle(line: str) -> Answer | _Pending:
            answer = spec.parse(line)
            return _PENDING if answer is None else answer

        return handle

    def _exchange(
        self,
        command: str,
        value: int | None,
        handle: Callable[[str], T | _Pending],
        timeout: float | None,
        *,
        extra: bytes = b"",
        discarded: Callable[[], int] | None = None,
    ) -> T:
        """Send one command and feed received lines to ``handle`` until it returns a result."""
        try:
            payload = format_command(command, value) + extra
        except LimitError as exc:
            raise LimitError(exc.message, device=self.device, command=command) from None
        wait = self.timeout if timeout is None else timeout
        if not self._lock.acquire(False):
            self._take_turn(command)
        try:
            if self._closed:
                raise ConnectionLost("the port is closed", device=self.device, command=command)
            self._given_up(command)  # nothing sent for a caller that is gone
            self._flush(command)
            self._write(payload, command)
            deadline = time.monotonic() + wait
            skipped = 0
            while True:
                line = self._next_line(command, deadline, wait)
                if is_unknown_command(line.text):
                    raise NotSupported(
                        "the device answered 'Unknown command'", device=self.device, command=command
                    )
                try:
                    result = handle(line.text)
                except ProtocolError as exc:  # a recognised answer with an impossible value
                    raise ProtocolError(exc.message, device=self.device, command=command) from None
                if not isinstance(result, _Pending):
                    self.discarded += skipped
                    return result
                if discarded is None:
                    skipped += 1
                else:
                    skipped = discarded()
                if skipped > self.max_discard:
                    self.discarded += skipped
                    raise ProtocolError(
                        f"no valid answer among {skipped} lines (last: {line.text[:60]!r})",
                        device=self.device,
                        command=command,
                    )
        finally:
            self._lock.release()

    def abandon(self, thread_ident: int) -> None:
        """Give up the exchange thread ``thread_ident`` runs, and its later ones until :meth:`resume`: each
        ends with GripperTimeout within ``_POLL_S`` (module docstring). Does not wait for that thread."""
        self._abandoned.add(thread_ident)

    def resume(self, thread_ident: int) -> None:
        """Thread ``thread_ident``'s next exchange is a new call: no longer given up."""
        self._abandoned.discard(thread_ident)

    def _given_up(self, command: str) -> None:
        if self._abandoned and threading.get_ident() in self._abandoned:
            raise GripperTimeout("abandoned: the caller stopped waiting", device=self.device, command=command)

    def _take_turn(self, command: str) -> None:
        """Wait for the exchange another thread runs, in slices, so an abandoned caller leaves at once."""
        while True:
            self._given_up(command)
            if self._lock.acquire(timeout=_POLL_S):
                return

    def _flush(self, command: str) -> None:
        """Drop stale input (a late answer to a timed-out command must not answer this one)."""
        self._lines.clear()
        self._splitter.reset()
        try:
            self._ser.reset_input_buffer()
        except _PORT_ERRORS as exc:
            raise self._lost(exc, command) from exc

    def _write(self, payload: bytes, command: str) -> None:
        try:
            self._ser.write(payload)
            log_uart_line(self.device, True, payload.decode("ascii", "replace"), time.time())
        except serial.SerialTimeoutException as exc:
            raise GripperTimeout(
                f"write not finished within {self.timeout} s", device=self.device, command=command
            ) from exc
        except _PORT_ERRORS as exc:
            raise self._lost(exc, command) from exc

    def _next_line(self, command: str, deadline: float, wait: float) -> Line:
        while not self._lines:
            self._given_up(command)
            if time.monotonic() >= deadline:
                raise GripperTimeout(
                    f"no answer within {wait:g} s (the firmware ignores unknown or malformed commands)",
                    device=self.device,
                    command=command,
                )
            try:
                waiting = self._ser.in_waiting
                data = self._ser.read(max(1, waiting))
            except _PORT_ERRORS as exc:
                raise self._lost(exc, command) from exc
            for event in self._splitter.feed(data):
                if isinstance(event, Line):
                    log_uart_line(self.device, False, event.text, time.time())
                    self._lines.append(event)
                else:
                    self.discarded += 1
        return self._lines.popleft()

    def _lost(self, exc: BaseException, command: str) -> GripperError:
        self.close()
        return ConnectionLost(f"serial port failed: {exc}", device=self.device, command=command)
