"""The simulated unit on Modbus RTU: requests of function 03 and 16 in, the model's bytes out as registers
(:mod:`grippers.drivers.schunk.rtu` says how an instance maps to registers). A frame for another device id
is ignored, as on a shared RS-485 line; an unknown function is answered with exception 1, an instance the
unit lacks or refuses with exception 2, a read of more registers than the parameter has with 3."""

from __future__ import annotations

from ... import modbus
from ..protocol import PARAMETERS
from ..rtu import bytes_of, registers_of
from .model import SchunkModel


class RtuSession:
    def __init__(self, model: SchunkModel, slave: int) -> None:
        self.model, self.slave = model, slave
        self.parser = modbus.RequestParser(slave)

    def feed(self, data: bytes, now: float) -> list[bytes]:
        return [self.answer(r, now) for r in self.parser.feed(data)]

    def answer(self, request: modbus.Request, now: float) -> bytes:
        inst = request.address + 1
        p = PARAMETERS.get(inst)
        if request.function == modbus.READ_HOLDING:
            data = self.model.read(inst, now) if p is not None else None
            if data is None or p is None:
                return modbus.exception_response(self.slave, request.function, 2)
            if request.count > p.registers:
                return modbus.exception_response(self.slave, request.function, 3)
            return modbus.read_response(self.slave, request.function, registers_of(data)[: request.count])
        if request.function == modbus.WRITE_MULTIPLE:
            if p is None or not self.model.write(inst, bytes_of(request.values), now):
                return modbus.exception_response(self.slave, request.function, 2)
            return modbus.write_response(self.slave, request.address, request.count)
        return modbus.exception_response(self.slave, request.function, 1)
