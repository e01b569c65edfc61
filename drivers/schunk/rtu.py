"""A SCHUNK unit's parameters over Modbus RTU (SCHUNK's driver: schunk_gripper_library/driver.py).

An instance ``INST`` is the holding registers from ``INST - 1``, as many as the parameter has; read with
function 03, written with function 16; each register carries two of the parameter's bytes in the web API's
order (the first byte is the register's high byte), so the codec of :mod:`.protocol` reads both transports.
The line is 115200 baud, 8 data bits, even parity, 1 stop bit; the unit's device id is 12 by default. A port
that refuses parity (a pseudo-terminal) is opened without it, as SCHUNK's driver does (``supports_parity`` in
schunk_gripper_library/utility.py).

The frames and the CRC are the generic Modbus RTU codec of :mod:`grippers.drivers.modbus` (function
codes 03 and 16 are all a SCHUNK unit needs), over the backend kit's serial link.
"""

from __future__ import annotations

import os

from .. import modbus
from ..errors import CommandFailed, GripperTimeout
from ..links import ByteLink, SerialLink
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


class RtuLink:
    """Reads and writes of parameters over Modbus RTU; one exchange at a time (the link's lock)."""

    def __init__(self, link: ByteLink, *, slave: int = DEFAULT_DEVICE_ID) -> None:
        self.link, self.slave = link, slave
        self.device = link.device
        self.parser = modbus.ResponseParser(slave)

    @classmethod
    def serial(
        cls,
        port: str,
        *,
        slave: int = DEFAULT_DEVICE_ID,
        baudrate: int = MODBUS_BAUDRATE,
        device: str,
        timeout: float,
    ) -> RtuLink:
        parity = "E" if supports_parity(port) else "N"
        return cls(
            SerialLink(port, baudrate, device=device, timeout=timeout, parity=parity, stopbits=1), slave=slave
        )

    @property
    def alive(self) -> bool:
        return self.link.alive

    def _exchange(self, request: bytes, function: int, count: int, command: str) -> modbus.Response:
        with self.link.lock:
            self.parser.reset()
            self.parser.expect(function, count)
            try:
                reply = self.link.exchange(request, self.parser.feed, command=command)[0]
            except GripperTimeout:
                self.link.discard_input()  # a late answer must not answer the next request
                raise
        if reply.exception is not None:
            raise CommandFailed(
                f"Modbus exception {reply.exception} to function {function}",
                status=reply.exception,
                status_name=_EXCEPTIONS.get(reply.exception, "exception"),
                device=self.device,
                command=command,
            )
        return reply

    def read(self, inst: int, command: str) -> bytes:
        count = parameter(inst).registers
        request = modbus.read_request(self.slave, inst - 1, count)
        reply = self._exchange(request, modbus.READ_HOLDING, count, command)
        return bytes_of(reply.values)

    def write(self, inst: int, data: bytes, command: str) -> None:
        values = registers_of(data)
        if len(values) != parameter(inst).registers:
            raise CommandFailed(f"{inst_text(inst)}: {len(data)} bytes", device=self.device, command=command)
        self._exchange(
            modbus.write_request(self.slave, inst - 1, values), modbus.WRITE_MULTIPLE, len(values), command
        )

    def close(self) -> None:
        self.link.close()


_EXCEPTIONS = {1: "ILLEGAL_FUNCTION", 2: "ILLEGAL_DATA_ADDRESS", 3: "ILLEGAL_DATA_VALUE", 4: "DEVICE_FAILURE"}
