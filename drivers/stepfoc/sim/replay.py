"""``grippers sim msg --replay FILE``: STEPFOC nodes on a CAN bus answering as a captured session did
(drivers/replay.py has the rules), from a candump log as ``grippers monitor -i -c --write`` saves it."""

from __future__ import annotations

import threading
from typing import Any

from ...captures import parse_candump
from ...replay import Mismatch, Script, Step, relative, report
from ...simkit import Sender
from .. import can_protocol as cp


def stepfoc_script(blob: bytes, name: str) -> Script:
    """Steps of a STEPFOC candump log: host frames are requests, the node frames after each its answers."""
    steps: list[Step] = []
    for frame in parse_candump(blob.decode("ascii", errors="replace").splitlines()):
        if frame.is_error or frame.is_extended or frame.is_fd:
            continue
        try:
            from_node = cp.decode_frame(frame.arbitration_id, frame.data, frame.is_remote).from_node
        except Exception:  # noqa: BLE001 - a frame the table does not know is not part of the session
            continue
        key = (frame.arbitration_id, frame.data, frame.is_remote)
        stamp = frame.timestamp or 0.0
        if not from_node:
            shown = f"{frame.arbitration_id:03X}#{'R' if frame.is_remote else frame.data.hex().upper()}"
            shown += f" ({cp.describe(frame.arbitration_id, frame.data, frame.is_remote)})"
            steps.append(Step(key, shown, [(stamp, None)]))
        elif steps:
            steps[-1].answers.append((stamp, key))
    return Script(relative(steps))


class StepfocReplayServer:
    """STEPFOC nodes on a CAN bus, answering host frames from a script."""

    def __init__(
        self, script: Script, interface: str, channel: str, time_scale: float = 1.0, **bus: Any
    ) -> None:
        import can

        self.script = script
        self.interface, self.channel = interface, channel
        self._sender = Sender(time_scale)
        self._bus = can.Bus(interface=interface, channel=channel, **bus)
        self._closed = threading.Event()
        self._thread = threading.Thread(target=self._run, name="stepfoc replay", daemon=True)
        self._thread.start()

    @property
    def url(self) -> str:
        # node id: bits 10-7 of the id (docs/protocols.md §2 CAN); requests here are (id, data, remote)
        nodes = sorted(
            {cp.unpack_id(s.request[0])[0] for s in self.script.steps if isinstance(s.request, tuple)}
        )
        return f"stepfoc+can://{self.interface}/{self.channel}?node={nodes[0] if nodes else 0}"

    def _send(self, key: Any) -> None:
        import can

        arbitration_id, data, remote = key
        self._bus.send(
            can.Message(
                arbitration_id=arbitration_id,
                data=b"" if remote else data,
                is_remote_frame=remote,
                is_extended_id=False,
                dlc=len(data),
            )
        )

    def _run(self) -> None:
        while not self._closed.is_set():
            try:
                msg = self._bus.recv(timeout=0.05)
            except Exception:  # noqa: BLE001 - a closed bus ends the loop
                return
            if msg is None or msg.is_error_frame or msg.is_extended_id:
                continue
            data = bytes(msg.data)
            try:
                if cp.decode_frame(msg.arbitration_id, data, msg.is_remote_frame).from_node:
                    continue  # our own answers, or another node's
            except Exception:  # noqa: BLE001
                pass
            key = (msg.arbitration_id, b"" if msg.is_remote_frame else data, bool(msg.is_remote_frame))
            shown = f"{msg.arbitration_id:03X}#{'R' if msg.is_remote_frame else data.hex().upper()}"
            outcome = self.script.answer(key, shown)
            if isinstance(outcome, Mismatch):
                report(outcome)
            else:
                self._sender.schedule(outcome, self._send)

    def close(self) -> None:
        self._closed.set()
        self._sender.close()
        self._thread.join(2)
        self._bus.shutdown()
