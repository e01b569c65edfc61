"""The backend kit: what every gripper family needs and a plugin should not rewrite (docs/backend-kit.md).

Four parts, each usable alone:

- **Byte links** (from :mod:`grippers.drivers.links`): :class:`ByteLink` over a serial line
  (:class:`SerialLink`, pyserial) or TCP (:class:`TcpLink`), opened from an address by :func:`open_link`.
  Every read has a finite deadline (:class:`~grippers.GripperTimeout`), a broken line raises
  :class:`~grippers.ConnectionLost` and sets :attr:`ByteLink.lost`, both naming the device and the command;
  :meth:`ByteLink.exchange` writes a request and feeds the reply to your sans-IO codec until it yields.
  :class:`LinkHolder` swaps a broken link for a fresh one on reconnection.
- **The simulator kit** (from :mod:`grippers.drivers.simkit`): :class:`SimServer` serves your device model
  on a pty or TCP, one :class:`DeviceSession` per connection; :class:`SimClock` is its scaled clock (pause,
  step, resume); :class:`FaultHooks` makes it misbehave on request (drop, delay, corrupt, truncate or
  duplicate a reply, garbage, silence, stall, close the connection).
- **The Modbus part** (from :mod:`grippers.drivers.modbus` and its siblings): :class:`ModbusClient`
  (registers read and written over any link, RTU or Modbus TCP, one exchange at a time with a deadline,
  exception replies as typed errors: :class:`IllegalDataAddress` ..., all :class:`ModbusException`, a
  :class:`~grippers.CommandFailed`; frames that lie as :class:`ModbusFrameError`), and the register-model
  simulator: :class:`RegisterModel` (what the registers hold and what a write does), :class:`RegisterMap`,
  :class:`ModbusSimServer` on a pty or TCP with the kit's clock and :class:`ModbusFaults`.
- **The polled-motion helper** (from :mod:`grippers.kit.motion`): :func:`poll_until` waits for a motion's
  end by polling the device, ends the wait when a stop or a newer motion comes (:class:`MotionEpochs`), at
  close or at the timeout, and maps the device's faults.
- **The command hooks** (docs/backends.md, "Hooks the commands call"): :class:`CommandHooks`, the one object
  a family offers the commands as its backend's ``commands`` (every hook with a default; :func:`commands_of`
  finds it), and what the hooks
  take and return, under one import with the rest: :class:`ProbeCandidate`, :class:`RawProbe`,
  :class:`Identity` and :func:`bus_query` (``grippers probe``), :class:`Dissector`, :class:`CanDissector` and
  :func:`monitor_record` (``grippers monitor``: one record of its JSON document, ``raw`` as hex text),
  :class:`SimCommand` (a family's own ``grippers sim``) and :class:`ServoTarget` (what a ``servo`` feature's
  ``send()`` receives). They are defined where the library uses them (the backends' ``command_hooks``,
  :mod:`grippers.servo`, the drivers' ``dissect``); this is where a plugin imports them from.

Everything here is public and stable for plugin authors; the drivers layer underneath imports nothing of
:mod:`grippers`, so a family's driver may use the same classes from ``grippers.drivers``.
"""

from __future__ import annotations

from grippers.drivers.dissect import CanDissector
from grippers.drivers.dissect import record as monitor_record
from grippers.drivers.links import (
    ByteLink,
    LinkHolder,
    Reconnectable,
    SerialLink,
    TcpLink,
    TraceFn,
    open_link,
)
from grippers.drivers.modbus import (
    ExceptionCode,
    IllegalDataAddress,
    IllegalDataValue,
    IllegalFunction,
    ModbusCRCError,
    ModbusException,
    ModbusFrameError,
    ModbusLengthError,
    ModbusUnitError,
    ServerDeviceBusy,
    ServerDeviceFailure,
    modbus_exception,
)
from grippers.drivers.modbus_client import ModbusClient
from grippers.drivers.modbus_model import RegisterMap, RegisterModel
from grippers.drivers.modbus_sim import ModbusFaults, ModbusSimServer
from grippers.drivers.simkit import (
    DeviceSession,
    Fault,
    FaultHooks,
    FaultKind,
    SimClock,
    SimServer,
    apply_fault,
    first_half,
    flip_last_byte,
)

from ..backends.command_hooks import (
    CommandHooks,
    Dissector,
    Identity,
    ProbeCandidate,
    RawProbe,
    SimCommand,
    bus_query,
    commands_of,
)
from ..servo import ServoTarget
from .motion import MotionEpochs, poll_until

__all__ = [
    "ByteLink",
    "CanDissector",
    "CommandHooks",
    "DeviceSession",
    "Dissector",
    "ExceptionCode",
    "Fault",
    "FaultHooks",
    "FaultKind",
    "Identity",
    "IllegalDataAddress",
    "IllegalDataValue",
    "IllegalFunction",
    "LinkHolder",
    "ModbusCRCError",
    "ModbusClient",
    "ModbusException",
    "ModbusFaults",
    "ModbusFrameError",
    "ModbusLengthError",
    "ModbusSimServer",
    "ModbusUnitError",
    "MotionEpochs",
    "ProbeCandidate",
    "RawProbe",
    "Reconnectable",
    "RegisterMap",
    "RegisterModel",
    "SerialLink",
    "ServerDeviceBusy",
    "ServerDeviceFailure",
    "ServoTarget",
    "SimClock",
    "SimCommand",
    "SimServer",
    "TcpLink",
    "TraceFn",
    "apply_fault",
    "bus_query",
    "commands_of",
    "first_half",
    "flip_last_byte",
    "modbus_exception",
    "monitor_record",
    "open_link",
    "poll_until",
]
