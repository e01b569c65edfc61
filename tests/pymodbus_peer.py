"""pymodbus, the independent Modbus peer of the tests, across its versions: it names the slave id
``device_id`` since 3.10 and ``slave`` before."""

from __future__ import annotations

import inspect
from typing import Any

from pymodbus.client import ModbusTcpClient

_ID = (
    "device_id"
    if "device_id" in inspect.signature(ModbusTcpClient.read_holding_registers).parameters
    else "slave"
)


def unit(slave: int) -> dict[str, Any]:
    """The keyword naming the slave id in a pymodbus client call: ``client.read_...(..., **unit(9))``."""
    return {_ID: slave}
