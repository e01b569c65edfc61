"""A SCHUNK unit over a parameter link (the web API or Modbus RTU): its parameters at connection, the
process data, and commands sent the way SCHUNK's driver sends them (schunk_gripper_library/driver.py):

1. write the empty command word (only bit 0, "no fast stop"), so the next word is a new command;
2. read 0x0040 and keep the "command received" bit (5);
3. write the command word; the command is taken once bit 5 has toggled (:class:`CommandTracker`).

Units are the unit's: µm, µm/s, % of the maximum gripping force; the backend converts to SI.
"""

from __future__ import annotations

import logging
from typing import Protocol

from ..errors import CommandFailed, ProtocolError
from .protocol import (
    BY_NAME,
    CONNECT_PARAMETERS,
    MODULE_TYPES,
    NO_COMMAND,
    OPTIONAL_PARAMETERS,
    PLC_INPUT,
    PLC_OUTPUT,
    CodecError,
    CommandTracker,
    ControlWord,
    Fieldbus,
    ProcessInput,
    decode,
    has_gpe,
)


class ParameterLink(Protocol):
    """What the client needs of a transport: one instance's bytes read or written, bounded in time."""

    device: str

    @property
    def alive(self) -> bool: ...

    def read(self, inst: int, command: str) -> bytes: ...

    def write(self, inst: int, data: bytes, command: str) -> None: ...

    def close(self) -> None: ...


class SchunkClient:
    """One unit: ``parameters`` (name -> value, floats in mm, mm/s, N) once :meth:`connect` read them."""

    def __init__(self, link: ParameterLink) -> None:
        self.link = link
        self.device = link.device
        self.fieldbus = Fieldbus.ETHERNET_IP
        self.parameters: dict[str, float | int | str | bool] = {}

    @property
    def alive(self) -> bool:
        return self.link.alive

    @property
    def module_type(self) -> str:
        code = self.parameters.get("module_type")
        return MODULE_TYPES.get(int(code), "") if isinstance(code, int) else ""

    @property
    def gpe_available(self) -> bool:
        return has_gpe(self.module_type)

    def connect(self, command: str = "open") -> None:
        """Read the fieldbus first (it sets the byte order), then every parameter SCHUNK's driver reads at
        connect (a missing one fails the connect, as there) and the optional ones it may lack."""
        raw = self.link.read(BY_NAME["fieldbus_type"].inst, command)
        try:
            self.fieldbus = Fieldbus(raw[0])
        except ValueError:
            raise ProtocolError(
                f"unknown fieldbus type {raw[0]} (0x1130; 1 PROFINET, 2 EIP, 3 EtherCAT, 7 Modbus)",
                device=self.device,
                command=command,
            ) from None
        values: dict[str, float | int | str | bool] = {"fieldbus_type": raw[0]}
        for name in CONNECT_PARAMETERS[1:]:
            values[name] = self.read_parameter(name, command)
        for name in OPTIONAL_PARAMETERS:
            try:
                values[name] = self.read_parameter(name, command)
            except CommandFailed:
                pass  # a unit without it: the profile's value stands
        if not isinstance(values["module_type"], int) or values["module_type"] not in MODULE_TYPES:
            raise ProtocolError(
                f"unknown module type {values['module_type']!r} (0x0500)", device=self.device, command=command
            )
        self.parameters = values

    def read_parameter(self, name: str, command: str) -> float | int | str | bool:
        p = BY_NAME[name]
        data = self.link.read(p.inst, command)
        self._logged(p.inst, data, write=False)
        try:
            return decode(p.inst, data, self.fieldbus)
        except CodecError as exc:
            raise ProtocolError(str(exc), device=self.device, command=command) from None

    def write_raw(self, name: str, data: bytes, command: str) -> None:
        self.link.write(BY_NAME[name].inst, data, command)

    def _logged(self, inst: int, data: bytes, *, write: bool) -> None:
        from ..dissect import wire_log

        if wire_log.isEnabledFor(logging.DEBUG):
            from .dissect import log_exchange

            log_exchange(self.device, self.transport, inst, data, self.fieldbus, write=write)

    @property
    def transport(self) -> str:
        return "rtu" if type(self.link).__name__ == "RtuLink" else "http"

    def read_input(self, command: str) -> ProcessInput:
        data = self.link.read(PLC_INPUT, command)
        self._logged(PLC_INPUT, data, write=False)
        try:
            return ProcessInput.decode(data, self.fieldbus)
        except CodecError as exc:
            raise ProtocolError(str(exc), device=self.device, command=command) from None

    def send(self, word: ControlWord, command: str) -> None:
        try:
            data = word.encode(self.fieldbus)
        except CodecError as exc:
            raise ProtocolError(str(exc), device=self.device, command=command) from None
        self._logged(PLC_OUTPUT, data, write=True)
        self.link.write(PLC_OUTPUT, data, command)

    def start(self, word: ControlWord, kind: str, command: str) -> CommandTracker:
        """Send ``word`` as a new command, SCHUNK's driver's three steps; the tracker tells its answer."""
        self.send(ControlWord(NO_COMMAND), command)
        tracker = CommandTracker.after(self.read_input(command), kind)
        self.send(word, command)
        return tracker

    def close(self) -> None:
        self.link.close()
