"""A calibration over the MSG's UART text interface, followed to its end (docs/protocols.md §2).

The calibrated bit stays set while a calibrated gripper recalibrates ("Firmware behaviour a client must
survive"), so the end is read from ``#Mode``: calibrating, then idle. Idle alone does not prove it ran (it may
never have started, or ended between two polls), so what ``#Mode`` showed since the last ``#Gripcal`` is kept
here, next to the verdicts drawn from it. The CAN side's counterpart is
:class:`~grippers.drivers.stepfoc.motion.CalibrationTracker`, fed by status frames instead of text answers.
"""

from __future__ import annotations

import time
from typing import Protocol

from ..errors import CommandFailed, GripperTimeout, NotSupported
from .motion import Verdict
from .uart_protocol import MODE_CALIBRATE, MODE_IDLE, Answer, GripInfo


class UartQueries(Protocol):
    """What a calibration asks of its UART client (:class:`~.uart_client.StepfocUart` provides it).

    Declared here so this module does not import the client that owns it (issue 32: no import circles).
    """

    device: str

    def query(self, name: str, value: int | None = None, *, timeout: float | None = None) -> Answer: ...

    def errors(self, *, timeout: float | None = None) -> list[str]: ...

    def mode(self, *, timeout: float | None = None) -> int | None: ...

    def position(self, setpoint: int | None = None, *, timeout: float | None = None) -> int: ...

    def gripinfo(self, *, timeout: float | None = None) -> GripInfo: ...


# a calibration ends with the jaws at the closed stop (position 255, docs/protocols.md §2)
CAL_AT_CLOSED = 250


class UartCalibration:
    """One :class:`~.uart_client.StepfocUart`'s calibration: its start, what ``#Mode`` showed of it since the
    last ``#Gripcal``, and the verdicts (the client's calibrate and calibration_* methods are these)."""

    def __init__(self, uart: UartQueries) -> None:
        self._uart = uart
        self.seen = False  # #Mode showed calibration mode since the last Gripcal

    def send(self, timeout: float | None) -> None:
        """``#Gripcal`` as it is, nothing checked first; forgets what was seen."""
        self.seen = False
        self._uart.query("Gripcal", timeout=timeout)

    def start(self, command: str) -> None:
        """``#Gripcal`` after ``#Error``: CommandFailed naming an active driver error instead."""
        try:
            causes = self._uart.errors()
        except (NotSupported, GripperTimeout):
            causes = []  # a firmware without #Error: the mode check below still catches a calibration that
            # never ran
        if causes:
            raise CommandFailed(
                f"cannot calibrate: driver error active ({', '.join(causes)}); acknowledge it first",
                status_name="error",
                device=self._uart.device,
                command=command,
            )
        self.send(None)

    def run(self, timeout: float, poll: float) -> None:
        """:meth:`start`, then poll every ``poll`` seconds until it has ended, ``timeout`` in all."""
        self.start("Gripcal")
        deadline = time.monotonic() + timeout
        while not self.ended("Gripcal"):
            if time.monotonic() >= deadline:
                raise GripperTimeout(
                    "calibration not finished before the timeout", device=self._uart.device, command="Gripcal"
                )
            time.sleep(poll)

    def verdict(self, command: str) -> Verdict:
        """RUNNING, ENDED or RETRY from one round of readings (see StepfocUart.calibration_verdict)."""
        uart = self._uart
        try:
            mode = uart.mode()
        except NotSupported:  # a firmware without #Mode: only a first calibration can be told
            return Verdict.ENDED if uart.gripinfo().calibrated else Verdict.RUNNING
        if mode == MODE_CALIBRATE:
            self.seen = True
            return Verdict.RUNNING
        if mode != MODE_IDLE:
            raise CommandFailed(
                "calibration aborted: the driver left calibration mode (a motion command?)",
                status_name="aborted",
                device=uart.device,
                command=command,
            )
        try:
            causes = uart.errors()
        except (NotSupported, GripperTimeout):
            causes = []
        if causes:
            raise CommandFailed(
                f"calibration stopped by a driver error: {', '.join(causes)}",
                status_name="error",
                device=uart.device,
                command=command,
            )
        if not self.seen:
            return Verdict.RETRY
        info = uart.gripinfo()
        position = uart.position()
        if info.estop:
            raise CommandFailed(
                "calibration aborted by the e-stop",
                status_name="fast_stop",
                device=uart.device,
                command=command,
            )
        if not info.calibrated:
            return Verdict.RETRY  # the firmware's calibration time-out: a new 62 starts from the beginning
        if position < CAL_AT_CLOSED:
            raise CommandFailed(
                f"calibration aborted or failed: the driver idles at position {position}",
                status_name="aborted",
                device=uart.device,
                command=command,
            )
        return Verdict.ENDED

    def ended(self, command: str) -> bool:
        """True once the calibration ended; CommandFailed for a RETRY."""
        verdict = self.verdict(command)
        if verdict is Verdict.RETRY:
            raise CommandFailed(
                "calibration did not run to its end (not seen running, or calibrated bit 0)",
                status_name="aborted",
                device=self._uart.device,
                command=command,
            )
        return verdict is Verdict.ENDED
