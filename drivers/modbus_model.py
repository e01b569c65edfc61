"""The register model of a simulated Modbus device, pure: requests in, response PDUs out, time passed in.

A family's simulator says what its registers hold and what a write does (:meth:`RegisterModel.read`,
:meth:`RegisterModel.write`); the rules every Modbus device keeps are here once (application protocol
V1.1b3 §6-7, serial line V1.02 §2.2): a request for another slave id is not answered, a broadcast (id 0)
write is carried out and not answered, a broadcast read is ignored, an unsupported function is answered with
exception 01, function 23 writes before it reads, and a model refuses a request by raising the typed error
of its exception code (``IllegalDataAddress`` for 02 ...), the same classes a client raises on receiving it.
:class:`RegisterMap` is the plainest model: registers in dictionaries.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence

from .modbus import (
    READ_HOLDING,
    READ_INPUT,
    READ_WRITE,
    WRITE_MULTIPLE,
    WRITES,
    IllegalDataAddress,
    IllegalDataValue,
    IllegalFunction,
    ModbusException,
    Request,
    exception_pdu,
    read_reply_pdu,
    rtu_frame,
    write_reply_pdu,
)

__all__ = ["BROADCAST", "RegisterMap", "RegisterModel"]

BROADCAST = 0  # serial line V1.02 §2.2: every slave carries a broadcast write out, none answers


class RegisterModel:
    """A device's registers, advanced in simulated time. Subclasses override :meth:`read` and :meth:`write`
    (and :meth:`received`, :meth:`advance` if the device keeps time); ``slave`` is its id, ``functions``
    the function codes it knows."""

    slave: int = 1
    functions: frozenset[int] = frozenset({READ_HOLDING, READ_INPUT, WRITE_MULTIPLE, READ_WRITE})

    def read(self, function: int, address: int, count: int, now: float) -> Sequence[int]:
        """The ``count`` registers from ``address`` (``function`` 03 holding, 04 input, 23 after its write);
        raise :class:`IllegalDataAddress` (or another :class:`ModbusException`) to refuse."""
        raise IllegalDataAddress()

    def write(self, address: int, values: tuple[int, ...], now: float) -> None:
        """Carry out a write of ``values`` from ``address``; raise a :class:`ModbusException` to refuse."""
        raise IllegalDataAddress()

    def received(self, request: Request, now: float) -> None:
        """Every request addressed to this device, before it is answered (a watchdog, a request count)."""

    def advance(self, now: float) -> None:
        """Run the device up to simulated time ``now`` (the simulator server calls it between requests)."""

    # -- the rules of every device ------------------------------------------------------------------------

    def addressed(self, slave: int) -> bool:
        return slave in (self.slave, BROADCAST)

    def answer(self, request: Request, now: float) -> bytes | None:
        """The response PDU to ``request`` at simulated time ``now``, None when the device stays silent."""
        if not self.addressed(request.slave):
            return None
        self.received(request, now)
        fc = request.function
        broadcast = request.slave == BROADCAST
        if broadcast and fc not in WRITES:
            return None
        try:
            if fc not in self.functions:
                raise IllegalFunction()
            if request.malformed:
                raise IllegalDataValue()
            if fc in WRITES:
                self.write(request.write_address, request.values, now)
            if fc == WRITE_MULTIPLE:
                pdu = write_reply_pdu(request.write_address, len(request.values))
            else:
                pdu = read_reply_pdu(fc, list(self.read(fc, request.address, request.count, now)))
        except ModbusException as exc:
            pdu = exception_pdu(fc, exc.status or 0)
        return None if broadcast else pdu

    def handle(self, request: Request, now: float) -> bytes | None:
        """:meth:`answer` as an RTU frame (None: silent)."""
        pdu = self.answer(request, now)
        return None if pdu is None else rtu_frame(self.slave, pdu)


class RegisterMap(RegisterModel):
    """Registers in dictionaries (address: value): ``holding`` (read with 03, written with 16 and 23) and
    ``inputs`` (read with 04). A read or write that touches an address the map lacks is answered with
    exception 02; ``read_only`` holding addresses refuse writes with 02 as well."""

    def __init__(
        self,
        slave: int = 1,
        *,
        holding: Mapping[int, int] | None = None,
        inputs: Mapping[int, int] | None = None,
        read_only: Sequence[int] = (),
    ) -> None:
        self.slave = slave
        self.holding = dict(holding or {})
        self.inputs = dict(inputs or {})
        self.read_only = frozenset(read_only)

    def read(self, function: int, address: int, count: int, now: float) -> Sequence[int]:
        table = self.inputs if function == READ_INPUT else self.holding
        try:
            return [table[a] for a in range(address, address + count)]
        except KeyError:
            raise IllegalDataAddress() from None

    def write(self, address: int, values: tuple[int, ...], now: float) -> None:
        span = range(address, address + len(values))
        if any(a not in self.holding or a in self.read_only for a in span):
            raise IllegalDataAddress()
        self.holding.update(zip(span, values, strict=True))
