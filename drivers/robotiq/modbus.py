"""The Modbus RTU codec the Robotiq family speaks: the generic one, :mod:`grippers.drivers.modbus`, shared
with the SCHUNK family since issue 41 (it was written here first). Every name it had stays importable from
here, so the family's modules, tests and benchmarks read as before."""

from __future__ import annotations

from ..modbus import *  # noqa: F403 - the public names, as before
from ..modbus import (  # noqa: F401 - the module's other names, as before
    FUNCTIONS,
    MAX_READ,
    MAX_RW_WRITE,
    MAX_WRITE,
    READS,
    decode_request,
    decode_response,
    silent_interval,
    wire_seconds,
)
