"""The Robotiq 2F-85 / 2F-140 / Hand-E register map, sans-IO: the request registers from 0x03E8 (rACT, rGTO,
rATR, rARD, rPR, rSP, rFR) and the status registers from 0x07D0 (gACT, gGTO, gSTA, gOBJ, gFLT, kFLT, gPR, gPO,
gCU). Facts and their sources: docs/protocols-robotiq.md §2.

Each block is six bytes in three registers, byte 2N in the high half of register N (big-endian, as Modbus
sends a register).
"""

from __future__ import annotations

import enum
from dataclasses import dataclass

COMMAND_ADDRESS = 0x03E8  # 1000: the output ("robot request") registers
STATUS_ADDRESS = 0x07D0  # 2000: the input ("gripper status") registers
BLOCK_REGISTERS = 3
DEFAULT_SLAVE = 9  # every Robotiq 2F / Hand-E ships as slave 9
BAUDRATE = 115200  # 8N1
FORWARDER_PORT = 54321  # a UR robot's tool-communication forwarder (docs/protocols-robotiq.md §4)
URCAP_PORT = 63352  # the Robotiq URCap's ASCII socket (docs/protocols-robotiq.md §5)

# ACTION REQUEST byte bits
ACT = 0x01
GTO = 0x08
ATR = 0x10
ARD = 0x20
CURRENT_MA_PER_COUNT = 10  # gCU: 0x10 reads 160 mA in the manual's example


class ObjectDetection(enum.IntEnum):
    """gOBJ (meaningful while gGTO is set)."""

    MOVING = 0  # fingers moving to the requested position, no object detected
    CONTACT_OPENING = 1  # stopped by a contact while opening: object detected
    CONTACT_CLOSING = 2  # stopped by a contact while closing: object detected
    AT_POSITION = 3  # at the requested position: no object, or the object was lost


class ActivationState(enum.IntEnum):
    """gSTA."""

    RESET = 0  # in reset (or automatic release)
    IN_PROGRESS = 1
    NOT_USED = 2
    COMPLETE = 3


class Fault(enum.IntEnum):
    """gFLT, the gripper's fault nibble."""

    NONE = 0x00
    ACTION_DELAYED = 0x05  # the (re)activation must complete before the action
    ACTIVATION_BIT = 0x07  # rACT must be set before the action
    TEMPERATURE = 0x08  # above 85 °C; cool below 80 °C
    NO_COMMUNICATION = 0x09  # no communication for at least 1 s
    UNDER_VOLTAGE = 0x0A
    AUTO_RELEASE_IN_PROGRESS = 0x0B
    INTERNAL = 0x0C
    ACTIVATION = 0x0D  # activation fault: interference or another error during activation
    OVERCURRENT = 0x0E
    AUTO_RELEASE_COMPLETE = 0x0F


# Names as GripperState.faults carries them, and the manual's words for error messages.
FAULT_NAMES: dict[int, str] = {
    Fault.ACTION_DELAYED: "action_delayed",
    Fault.ACTIVATION_BIT: "activation_bit_not_set",
    Fault.TEMPERATURE: "over_temperature",
    Fault.NO_COMMUNICATION: "no_communication",
    Fault.UNDER_VOLTAGE: "under_voltage",
    Fault.AUTO_RELEASE_IN_PROGRESS: "automatic_release_in_progress",
    Fault.INTERNAL: "internal_fault",
    Fault.ACTIVATION: "activation_fault",
    Fault.OVERCURRENT: "overcurrent",
    Fault.AUTO_RELEASE_COMPLETE: "automatic_release_completed",
}
FAULT_TEXT: dict[int, str] = {
    Fault.ACTION_DELAYED: "action delayed: the activation must complete before the action",
    Fault.ACTIVATION_BIT: "the activation bit (rACT) must be set before the action",
    Fault.TEMPERATURE: "maximum operating temperature exceeded (>= 85 °C); let it cool below 80 °C",
    Fault.NO_COMMUNICATION: "no communication during at least 1 second",
    Fault.UNDER_VOLTAGE: "under minimum operating voltage",
    Fault.AUTO_RELEASE_IN_PROGRESS: "automatic release in progress",
    Fault.INTERNAL: "internal fault",
    Fault.ACTIVATION: "activation fault: check for interference or another error",
    Fault.OVERCURRENT: "overcurrent triggered",
    Fault.AUTO_RELEASE_COMPLETE: "automatic release completed",
}
# Major faults (status LED blinking red/blue): only a reset, rACT cleared then set, clears them.
MAJOR_FAULTS = frozenset(range(0x0A, 0x10))


def fault_name(code: int) -> str:
    return FAULT_NAMES.get(code, f"fault_0x{code:02x}")


def fault_text(code: int) -> str:
    return FAULT_TEXT.get(code, f"fault 0x{code:02X} (not in the manual)")


@dataclass(frozen=True, slots=True)
class Command:
    """The request block: rACT, rGTO, rATR, rARD and the position, speed and force bytes."""

    act: bool = False
    gto: bool = False
    atr: bool = False
    ard: bool = False
    position: int = 0
    speed: int = 0
    force: int = 0

    def __post_init__(self) -> None:
        for name in ("position", "speed", "force"):
            value = getattr(self, name)
            if not isinstance(value, int) or not 0 <= value <= 255:
                raise ValueError(f"{name} must be a byte 0..255, not {value!r}")

    @property
    def action(self) -> int:
        return (
            (ACT if self.act else 0)
            | (GTO if self.gto else 0)
            | (ATR if self.atr else 0)
            | (ARD if self.ard else 0)
        )

    def registers(self) -> tuple[int, int, int]:
        return (self.action << 8, self.position, self.speed << 8 | self.force)

    @classmethod
    def from_registers(cls, regs: tuple[int, ...] | list[int]) -> Command:
        r = list(regs) + [0] * (BLOCK_REGISTERS - len(regs))
        action = r[0] >> 8
        return cls(
            act=bool(action & ACT),
            gto=bool(action & GTO),
            atr=bool(action & ATR),
            ard=bool(action & ARD),
            position=r[1] & 0xFF,
            speed=r[2] >> 8,
            force=r[2] & 0xFF,
        )


@dataclass(frozen=True, slots=True)
class Status:
    """The status block, decoded."""

    act: bool
    gto: bool
    sta: ActivationState
    obj: ObjectDetection
    fault: int  # gFLT
    controller_fault: int  # kFLT (a Robotiq Universal Controller's; 0 on a bare gripper)
    position_echo: int  # gPR
    position: int  # gPO
    current: int | None  # gCU, ~10 mA per count; None where it is not reported (the URCap socket)

    @property
    def activated(self) -> bool:
        return self.act and self.sta == ActivationState.COMPLETE

    @property
    def moving(self) -> bool:
        return self.activated and self.gto and self.obj == ObjectDetection.MOVING

    @property
    def current_ma(self) -> int | None:
        return None if self.current is None else self.current * CURRENT_MA_PER_COUNT

    @property
    def major_fault(self) -> bool:
        return self.fault in MAJOR_FAULTS

    def registers(self) -> tuple[int, int, int]:
        byte0 = (ACT if self.act else 0) | (GTO if self.gto else 0) | int(self.sta) << 4 | int(self.obj) << 6
        byte2 = (self.controller_fault & 0x0F) << 4 | (self.fault & 0x0F)
        return (byte0 << 8, byte2 << 8 | self.position_echo, self.position << 8 | (self.current or 0))

    @classmethod
    def from_registers(cls, regs: tuple[int, ...] | list[int]) -> Status:
        """Decode 1 to 3 status registers (the manual's activation poll reads only the first)."""
        r = list(regs) + [0] * (BLOCK_REGISTERS - len(regs))
        b0, b2 = r[0] >> 8, r[1] >> 8
        return cls(
            act=bool(b0 & ACT),
            gto=bool(b0 & GTO),
            sta=ActivationState((b0 >> 4) & 3),
            obj=ObjectDetection((b0 >> 6) & 3),
            fault=b2 & 0x0F,
            controller_fault=b2 >> 4,
            position_echo=r[1] & 0xFF,
            position=r[2] >> 8,
            current=r[2] & 0xFF,
        )

    def describe(self) -> str:
        """One line, as the monitor and -vv print it."""
        return (
            f"gACT={int(self.act)} gGTO={int(self.gto)} gSTA={self.sta.name} gOBJ={self.obj.name} "
            f"gFLT=0x{self.fault:X} kFLT=0x{self.controller_fault:X} gPR={self.position_echo} "
            f"gPO={self.position} gCU={'-' if self.current is None else self.current}"
        )
