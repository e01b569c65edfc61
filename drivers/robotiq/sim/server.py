"""Servers around :class:`~.model.RobotiqModel`, on the simulator kit's
:class:`~grippers.drivers.simkit.SimServer`: a pty for the RTU line (as an RS-485 adapter's /dev/ttyUSB0), TCP
carrying the same raw RTU frames (as a UR robot's tool-communication forwarder), and the URCap's ASCII socket
in front of the same model.

What is Robotiq's here is the register model and the URCap session (URCap lines read with the URCap codec).
The kit brings the rest: the Modbus session (RTU requests parsed with the codec, silent on another slave id
or a bad CRC, as the device is), the scaled clock (tests that must not race it :meth:`pause` and
:meth:`step` it), the fault hooks (drop, delay, corrupt, truncate, duplicate, garbage, silence, stall, close,
and on RTU exception replies) and the one server thread.
"""

from __future__ import annotations

from ...modbus_sim import ModbusFaults, ModbusSession
from ...simkit import SimServer
from ...urls import on_transport
from .. import urcap_protocol as urcap
from ..modbus import READ_HOLDING, WRITE_MULTIPLE, Request
from ..registers import COMMAND_ADDRESS, STATUS_ADDRESS
from .model import RobotiqModel

__all__ = ["RobotiqSimServer", "serve"]


class UrcapSession:
    """The URCap's socket in front of the model: SET is a write of the request block, answered by the three
    bytes ``ack`` with no line end, as the controller does; GET a read of the status, answered ``VAR VALUE``
    and a line end (docs/protocols-robotiq.md §5 names the public sources). A line it does not understand
    gets no answer."""

    def __init__(self, model: RobotiqModel) -> None:
        self.model = model
        self.lines = bytearray()

    def feed(self, data: bytes, now: float) -> list[bytes]:
        self.lines += data
        out = []
        while b"\n" in self.lines:
            raw, _, rest = bytes(self.lines).partition(b"\n")
            self.lines = bytearray(rest)
            try:
                verb, arg = urcap.parse_command(raw.decode("ascii", "replace"))
            except ValueError:
                continue
            slave = self.model.slave
            if isinstance(arg, dict):  # SET
                cmd = urcap.command_after_set(self.model.command, arg)
                self.model.handle(
                    Request(slave, WRITE_MULTIPLE, COMMAND_ADDRESS, 3, COMMAND_ADDRESS, cmd.registers()), now
                )
                out.append(urcap.ACK_REPLY)
            else:  # GET: the status as a read of it now
                self.model.handle(Request(slave, READ_HOLDING, STATUS_ADDRESS, 3), now)
                value = urcap.variable_of(arg, self.model.status(), self.model.command)
                out.append(urcap.get_reply(arg, value))
        return out


class RobotiqSimServer(SimServer):
    """A running simulator: ``.url``, ``.model``, ``.faults``, ``.clock``; ``close()`` stops it.

    Tests that change the model (``part_width_mm``, :meth:`RobotiqModel.inject_fault`) hold ``.lock``.
    """

    def __init__(
        self, model: RobotiqModel, listen: str, *, time_scale: float = 1.0, family: str = "robotiq"
    ) -> None:
        self.model = model
        listen, protocol = on_transport(listen, {"urcap": "tcp"})
        is_urcap = protocol == "urcap"
        faults = ModbusFaults()
        super().__init__(
            listen,
            (lambda: UrcapSession(model)) if is_urcap else (lambda: ModbusSession(model, "rtu", faults)),
            family=family,
            time_scale=time_scale,
            advance=model.advance,
            faults=faults,
        )
        if is_urcap:  # the URCap socket's own scheme (the backend's url_protocols)
            self.url = self.url.replace(f"{family}+tcp://", f"{family}+urcap://", 1)


def serve(
    model: RobotiqModel, listen: str = "tcp://127.0.0.1:0", *, time_scale: float = 1.0
) -> RobotiqSimServer:
    """Start a simulator: ``listen`` is ``pty`` (the RTU line), ``tcp://HOST:PORT`` (a forwarder; port 0: any
    free port) or ``urcap://HOST:PORT`` (the URCap's ASCII socket in front of the same model)."""
    return RobotiqSimServer(model, listen, time_scale=time_scale)
