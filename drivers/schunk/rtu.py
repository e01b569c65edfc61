"""A SCHUNK unit's parameters over Modbus RTU (SCHUNK's driver: schunk_gripper_library/driver.py).

An instance ``INST`` is the holding registers from ``INST - 1``, as many as the parameter has; read with
function 03, written with function 16; each register carries two of the parameter's bytes in the web API's
order (the first byte is the register's high byte), so the codec of :mod:`.protocol` reads both transports.
The line is 115200 baud, 8 data bits, even parity, 1 stop bit; the unit's device id is 12 by default. A port
that refuses parity (a pseudo-terminal) is opened without it, as SCHUNK's driver does (``supports_parity`` in
schunk_gripper_library/utility.py).

The exchange is the backend kit's Modbus client (:mod:`grippers.drivers.modbus_client`: function codes 03
and 16 are all a SCHUNK unit needs) over its serial link.
"""

from __future__ import annotations

import os
from typing import Any, Self

from ..errors import CommandFailed
from ..modbus_client import ModbusClient
from .protocol import DEFAULT_DEVICE_ID, MODBUS_BAUDRATE, inst_text, parameter


def supports_parity(port: str) -> bool:
    """Whether the port takes even parity (a pseudo-terminal may not): the port opened with it and set up
    again, as the serial link will do at its first read."""
    import serial

    if os.path.realpath(port).startswith("/dev/pts/"):
        return (
            False  # a pseudo-terminal: Linux refuses PARENB there (EINVAL), under some namespaces only later
        )
    try:
        with serial.serial_for_url(port, MODBUS_BAUDRATE, parity="E", timeout=0, exclusive=False) as probe:
            probe.timeout = 0.01  # pyserial applies every setting again here (termios on POSIX)
        return True
    except (OSError, ValueError, serial.SerialException, TypeError):
        return False
    except Exception as exc:  # termios.error is no OSError
        if type(exc).__name__ == "error":
            return False
        raise


def registers_of(data: bytes) -> list[int]:
    """A parameter's bytes as registers: two bytes each, the first the high byte."""
    if len(data) % 2:
        data += b"\x00"
    return [int.from_bytes(data[i : i + 2], "big") for i in range(0, len(data), 2)]


def bytes_of(registers: tuple[int, ...] | list[int]) -> bytes:
    return b"".join(r.to_bytes(2, "big") for r in registers)


class RtuLink(ModbusClient):
    """Reads and writes of parameters over Modbus RTU: the kit's :class:`ModbusClient` (one exchange at a
    time, a late reply dropped, exception replies as typed errors) with SCHUNK's instance-to-register map."""

    @classmethod
    def serial(  # SCHUNK's line: even parity where the port takes it
        cls,
        port: str,
        *,
        baudrate: int = MODBUS_BAUDRATE,
        slave: int = DEFAULT_DEVICE_ID,
        serial_options: dict[str, Any] | None = None,
        **kw: Any,
    ) -> Self:
        options = {"parity": "E" if supports_parity(port) else "N", "stopbits": 1, **(serial_options or {})}
        return super().serial(port, baudrate=baudrate, slave=slave, serial_options=options, **kw)

    def read(self, inst: int, command: str) -> bytes:
        return bytes_of(self.read_holding_registers(inst - 1, parameter(inst).registers, command=command))

    def write(self, inst: int, data: bytes, command: str) -> None:
        values = registers_of(data)
        if len(values) != parameter(inst).registers:
            raise CommandFailed(f"{inst_text(inst)}: {len(data)} bytes", device=self.device, command=command)
        self.write_registers(inst - 1, values, command=command)
