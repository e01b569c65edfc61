"""The simulated unit's registers on Modbus RTU: the kit's register model over :class:`SchunkModel`
(:mod:`grippers.drivers.schunk.rtu` says how an instance maps to registers). Function 03 reads and 16
writes; the kit's rules answer the rest (another device id ignored as on a shared RS-485 line, another
function with exception 1). An instance the unit lacks or refuses is answered with exception 2, a read of
more registers than the parameter has with 3."""

from __future__ import annotations

from ...modbus import READ_HOLDING, WRITE_MULTIPLE, IllegalDataAddress, IllegalDataValue
from ...modbus_model import RegisterModel
from ..protocol import PARAMETERS
from ..rtu import bytes_of, registers_of
from .model import SchunkModel


class SchunkRegisters(RegisterModel):
    functions = frozenset({READ_HOLDING, WRITE_MULTIPLE})

    def __init__(self, model: SchunkModel, slave: int) -> None:
        self.model, self.slave = model, slave

    def advance(self, now: float) -> None:
        self.model.advance(now)

    def read(self, function: int, address: int, count: int, now: float) -> list[int]:
        inst = address + 1
        p = PARAMETERS.get(inst)
        data = self.model.read(inst, now) if p is not None else None
        if data is None or p is None:
            raise IllegalDataAddress()
        if count > p.registers:
            raise IllegalDataValue()
        return registers_of(data)[:count]

    def write(self, address: int, values: tuple[int, ...], now: float) -> None:
        inst = address + 1
        if inst not in PARAMETERS or not self.model.write(inst, bytes_of(values), now):
            raise IllegalDataAddress()
