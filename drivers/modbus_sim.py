"""A register model served as a Modbus device, on the simulator kit: RTU on a pty (an RS-485 adapter's
``/dev/ttyUSB0``), RTU bytes over TCP (a forwarder or a transparent gateway), or Modbus TCP (MBAP).

What a family writes is its :class:`~.modbus_model.RegisterModel`; this module adds the one session per
connection that parses requests with the driver's own codec, asks the model and frames its answer, and
:class:`ModbusFaults`, the kit's fault hooks plus what only a Modbus device does wrong: exception replies on
request (a busy device, a failing one), whatever the model would have answered. The clock and the faults
can be given at construction, so a test holds the device still or queues its faults before the first byte.
"""

from __future__ import annotations

from collections import deque
from dataclasses import replace

from .modbus import ModbusFrameError, RequestParser, exception_pdu, rtu_frame
from .modbus_model import RegisterModel
from .modbus_tcp import ANY_UNIT, MbapRequestParser, mbap_frame
from .simkit import FaultHooks, SimClock, SimServer

__all__ = ["ModbusFaults", "ModbusSession", "ModbusSimServer"]


class ModbusFaults(FaultHooks):
    """:class:`FaultHooks` (drop, delay, corrupt, truncate, duplicate, garbage, silence, stall, close) and
    exception replies: :meth:`exception_replies` makes the next ``count`` requests addressed to the device
    answered with exception ``code`` instead of what the model says (the model does not see them)."""

    def __init__(self) -> None:
        super().__init__()
        self._exceptions: deque[int] = deque()

    def exception_replies(self, code: int, count: int = 1) -> None:
        if not 1 <= code <= 0xFF:
            raise ValueError(f"an exception code is 1..255, not {code!r}")
        with self._lock:
            self._exceptions.extend([code] * count)

    def take_exception(self) -> int | None:
        with self._lock:
            return self._exceptions.popleft() if self._exceptions else None

    def clear(self) -> None:
        with self._lock:
            self._exceptions.clear()
        super().clear()


class ModbusSession:
    """One connection to the device: requests parsed (``framing`` ``"rtu"`` or ``"tcp"``), answered by the
    model, framed back. A Modbus TCP header that is not Modbus's drops the connection's buffer (nothing after
    it can be framed), as :mod:`.modbus_tcp` says."""

    def __init__(self, model: RegisterModel, framing: str = "rtu", faults: FaultHooks | None = None) -> None:
        if framing not in ("rtu", "tcp"):
            raise ValueError(f"framing must be 'rtu' or 'tcp', not {framing!r}")
        self.model, self.framing = model, framing
        self.faults = faults if isinstance(faults, ModbusFaults) else None
        self.parser: RequestParser | MbapRequestParser = (
            RequestParser(None) if framing == "rtu" else MbapRequestParser()
        )

    def feed(self, data: bytes, now: float) -> list[bytes]:
        try:
            requests = self.parser.feed(data)
        except ModbusFrameError:
            return []
        out = []
        for req in requests:
            unit = req.slave  # echoed on Modbus TCP
            if self.framing == "tcp" and unit == ANY_UNIT:
                req = replace(req, slave=self.model.slave)
            code = self.faults.take_exception() if self.faults and self.model.addressed(req.slave) else None
            pdu = exception_pdu(req.function, code) if code else self.model.answer(req, now)
            if pdu is None:
                continue
            if self.framing == "rtu":
                out.append(rtu_frame(self.model.slave, pdu))
            else:
                out.append(mbap_frame(req.transaction, unit, pdu))
        return out


class ModbusSimServer(SimServer):
    """``model`` served where ``listen`` says (``pty``, ``tcp://HOST:PORT``; port 0: a free one) with
    ``framing`` ``"rtu"`` (the default; over TCP: RTU bytes, as a forwarder carries them) or ``"tcp"``
    (Modbus TCP). ``.model``, ``.url``, ``.clock``, ``.faults`` (:class:`ModbusFaults` unless others were
    given), ``.lock``; ``close()`` stops it. ``clock`` and ``faults`` given here are used from the start."""

    faults: FaultHooks

    def __init__(
        self,
        model: RegisterModel,
        listen: str = "tcp://127.0.0.1:0",
        *,
        framing: str = "rtu",
        family: str = "modbus",
        time_scale: float = 1.0,
        clock: SimClock | None = None,
        faults: FaultHooks | None = None,
    ) -> None:
        self.model = model
        self.framing = framing
        hooks = faults if faults is not None else ModbusFaults()
        ModbusSession(model, framing)  # a bad framing is refused here, not in the server's thread
        super().__init__(
            listen,
            lambda: ModbusSession(model, framing, hooks),
            family=family,
            time_scale=time_scale,
            advance=model.advance,
            clock=clock,
            faults=hooks,
        )
