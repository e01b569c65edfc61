"""``grippers sim wsg|msg --replay FILE``: answer as a captured session did, so a capture from a real
gripper becomes a regression fixture.

:class:`Script` is the sans-IO core: the capture as steps (one request, the answers that followed it and
their delays), and :meth:`Script.answer` deciding what a new request gets. Rules, in order: the next request
of the capture gets its answers; a repeat of the request answered last gets the same answers again (a client
polls a state a varying number of times while a motion runs); requests of the capture that only repeat the
one before them may be skipped to reach a match (the client polled fewer times). Anything else is a
mismatch: reported with both requests, and not answered, so the test that runs against the replay fails
instead of passing on answers meant for another request.

Transports: the WSG over TCP (captures: hex dumps with directions, as ``monitor --proxy --write`` saves
them), STEPFOC over CAN (candump logs, as ``monitor -i -c --write`` saves them).
"""

from __future__ import annotations

import socket
import sys
import threading
from collections.abc import Callable, Hashable
from dataclasses import dataclass, field
from typing import Any

from .captures import FROM_DEVICE, TO_DEVICE


@dataclass
class Step:
    request: Hashable
    shown: str  # the request for people (hex, or a decoded line)
    answers: list[tuple[float, Any]] = field(default_factory=list)  # (seconds after the request, answer)


@dataclass(frozen=True)
class Mismatch:
    index: int  # the step expected next
    expected: str | None  # None: the capture has ended
    got: str

    def __str__(self) -> str:
        if self.expected is None:
            return f"request after the end of the capture: {self.got}"
        return f"request {self.index + 1} differs from the capture: expected {self.expected}, got {self.got}"


class Script:
    """The capture's steps and the position reached; pure (no clocks, no I/O)."""

    def __init__(self, steps: list[Step]) -> None:
        if not steps:
            raise ValueError("the capture holds no request")
        self.steps = steps
        self.next = 0
        self.last: Step | None = None
        self.answered = 0
        self.repeated = 0
        self.mismatches: list[Mismatch] = []

    def answer(self, request: Hashable, shown: str) -> list[tuple[float, Any]] | Mismatch:
        index = self.next
        while index < len(self.steps):
            step = self.steps[index]
            if step.request == request:
                self.next, self.last = index + 1, step
                self.answered += 1
                return step.answers
            repeats_previous = index > 0 and step.request == self.steps[index - 1].request
            if not repeats_previous:
                break
            index += 1  # a poll the client did not repeat as often this time
        if self.last is not None and self.last.request == request:
            self.repeated += 1
            return self.last.answers
        expected = self.steps[self.next].shown if self.next < len(self.steps) else None
        mismatch = Mismatch(self.next, expected, shown)
        self.mismatches.append(mismatch)
        return mismatch

    @property
    def done(self) -> bool:
        return self.next >= len(self.steps)


# --- captures to scripts ------------------------------------------------------------------------------------


def wsg_script(blob: bytes, name: str) -> Script:
    """Steps of a WSG byte capture (hex dump with directions); each packet reassembled per direction."""
    from grippers.drivers.wsg import commands
    from grippers.drivers.wsg.protocol import Packet, PacketParser

    from .captures import parse_hex_dump

    parsers = {TO_DEVICE: PacketParser(), FROM_DEVICE: PacketParser()}
    steps: list[Step] = []
    for chunk in parse_hex_dump(blob.decode("ascii", errors="replace").splitlines()):
        if chunk.direction not in parsers:
            raise ValueError(f"{name}: line {chunk.line} has no direction (> or <); a replay needs both")
        for item in parsers[chunk.direction].feed(chunk.data):
            if not isinstance(item, Packet):
                continue  # noise in the capture is not replayed
            raw = item.encode()
            if chunk.direction == TO_DEVICE:
                shown = f"{commands.describe(item, 'request')} [{raw.hex()}]"
                steps.append(Step(raw, shown, []))
                steps[-1].answers.append((chunk.timestamp or 0.0, None))  # the request's time, removed below
            elif steps:
                steps[-1].answers.append((chunk.timestamp or 0.0, raw))
    return Script(_relative(steps))


def stepfoc_script(blob: bytes, name: str) -> Script:
    """Steps of a STEPFOC candump log: host frames are requests, the node frames after each its answers."""
    from grippers.drivers.stepfoc import can_protocol as cp

    from .captures import parse_candump

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
    return Script(_relative(steps))


def _relative(steps: list[Step]) -> list[Step]:
    """Answer times as seconds after their request (the first entry of each step holds the request's time)."""
    for step in steps:
        t0 = step.answers[0][0]
        step.answers = [(max(0.0, t - t0), a) for t, a in step.answers[1:]]
    return steps


# --- servers ------------------------------------------------------------------------------------------------


class _Sender:
    """Sends each answer at its recorded delay (divided by the time scale), on timers that close() cancels."""

    def __init__(self, time_scale: float) -> None:
        self.time_scale = time_scale
        self._timers: list[threading.Timer] = []
        self._lock = threading.Lock()

    def schedule(self, answers: list[tuple[float, Any]], send: Callable[[Any], None]) -> None:
        for delay, answer in answers:
            timer = threading.Timer(delay / self.time_scale, _quiet(send), args=(answer,))
            timer.daemon = True
            with self._lock:
                self._timers = [t for t in self._timers if t.is_alive()]
                self._timers.append(timer)
            timer.start()

    def close(self) -> None:
        with self._lock:
            for timer in self._timers:
                timer.cancel()


def _quiet(send: Callable[[Any], None]) -> Callable[[Any], None]:
    def run(answer: Any) -> None:
        try:
            send(answer)
        except (OSError, ValueError):  # the client went away meanwhile
            pass

    return run


def _report(mismatch: Mismatch, stream: Any = None) -> None:
    print(f"grippers sim: replay: {mismatch}; not answered", file=stream or sys.stderr, flush=True)


class WsgReplayServer:
    """The WSG over TCP, answering from a script; one connection at a time continues the same script."""

    def __init__(self, script: Script, host: str, port: int, time_scale: float = 1.0) -> None:
        self.script = script
        self._sender = _Sender(time_scale)
        self._listener = socket.create_server((host, port))
        self._listener.settimeout(0.05)  # close() alone does not wake a blocked accept() on Linux
        self._closed = threading.Event()
        self._lock = threading.Lock()
        self._conns: list[socket.socket] = []
        self._thread = threading.Thread(target=self._accept, name="wsg replay", daemon=True)
        self._thread.start()

    @property
    def url(self) -> str:
        host, port = self._listener.getsockname()[:2]
        return f"wsg+tcp://{host}:{port}"

    def _accept(self) -> None:
        while not self._closed.is_set():
            try:
                conn, _ = self._listener.accept()
            except TimeoutError:
                continue
            except OSError:
                return
            conn.settimeout(None)
            with self._lock:
                self._conns.append(conn)
            threading.Thread(target=self._serve, args=(conn,), daemon=True).start()

    def _serve(self, conn: socket.socket) -> None:
        from grippers.drivers.wsg import commands
        from grippers.drivers.wsg.protocol import Packet, PacketParser

        parser = PacketParser()
        with conn:
            while not self._closed.is_set():
                try:
                    data = conn.recv(4096)
                except OSError:
                    return
                if not data:
                    return
                for item in parser.feed(data):
                    if not isinstance(item, Packet):
                        continue
                    raw = item.encode()
                    shown = f"{commands.describe(item, 'request')} [{raw.hex()}]"
                    with self._lock:
                        outcome = self.script.answer(raw, shown)
                    if isinstance(outcome, Mismatch):
                        _report(outcome)
                    else:
                        self._sender.schedule(outcome, conn.sendall)

    def close(self) -> None:
        self._closed.set()
        self._sender.close()
        self._listener.close()
        with self._lock:
            for conn in self._conns:
                try:
                    conn.shutdown(socket.SHUT_RDWR)
                except OSError:
                    pass
                conn.close()
        self._thread.join(2)


class StepfocReplayServer:
    """STEPFOC nodes on a CAN bus, answering host frames from a script."""

    def __init__(
        self, script: Script, interface: str, channel: str, time_scale: float = 1.0, **bus: Any
    ) -> None:
        import can

        self.script = script
        self.interface, self.channel = interface, channel
        self._sender = _Sender(time_scale)
        self._bus = can.Bus(interface=interface, channel=channel, **bus)
        self._closed = threading.Event()
        self._thread = threading.Thread(target=self._run, name="stepfoc replay", daemon=True)
        self._thread.start()

    @property
    def url(self) -> str:
        nodes = sorted({s.request[0] >> 7 for s in self.script.steps})  # node id: bits 10-7 (§2 CAN)
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
        from grippers.drivers.stepfoc import can_protocol as cp

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
                _report(outcome)
            else:
                self._sender.schedule(outcome, self._send)

    def close(self) -> None:
        self._closed.set()
        self._sender.close()
        self._thread.join(2)
        self._bus.shutdown()


def summary(script: Script) -> str:
    left = len(script.steps) - script.next
    return (
        f"grippers sim: replay: {script.answered} request(s) answered, {script.repeated} repeated, "
        f"{len(script.mismatches)} mismatch(es), {left} of {len(script.steps)} not reached"
    )
