"""Serve one or several simulated MSG nodes on a python-can bus (virtual, udp_multicast, socketcan, …).

The server is thin: one thread reads the bus, advances every model to the scaled clock, lets the model whose
node id matches answer, and applies the test's :class:`~grippers.drivers.simkit.FaultHooks` to each reply.
Heartbeats (command 9) are sent from the same thread; only replies a test asked to DELAY leave from a timer
thread.

Reach: python-can's ``udp_multicast`` bus binds to all interfaces and sends with TTL / hop limit 1, so its
frames stay on the local link but are NOT confined to loopback; on Linux every bus on the host with the same
port sees every group (docs/protocols.md §2, "Testing without CAN hardware"). Use ``virtual`` in-process.
"""

from __future__ import annotations

import threading
from collections.abc import Iterable
from typing import Any

import can

from ...canlink import is_link_failure, standard_message
from ...closing import Closing
from ...errors import ConnectionLost
from ...simkit import FaultHooks, SimClock, apply_fault, first_half, flip_last_byte
from ..can_protocol import DEFAULT_BITRATE, MAX_NODE, CanFrame, parse_can_url
from .model import MsgModel

__all__ = ["CanSimServer", "parse_can_url", "serve_can"]

_POLL_S = 0.02  # longest wall time the reader blocks, so heartbeats and close() stay prompt


class CanSimServer(Closing):
    """A running CAN simulator. ``models`` share one bus; ``url`` names the first node for a client."""

    def __init__(
        self,
        models: list[MsgModel],
        bus: can.BusABC,
        *,
        interface: str,
        channel: str,
        own_bus: bool,
        time_scale: float = 1.0,
        clock: SimClock | None = None,
    ) -> None:
        self.models = models
        self.bus = bus
        self.interface = interface
        self.channel = channel
        self.faults = FaultHooks()
        self.clock = clock or SimClock(time_scale)
        self.error: BaseException | None = None  # what stopped the thread, if anything did
        self._own_bus = own_bus
        self._lock = threading.Lock()  # guards the models against a test poking them from another thread
        self._stop = threading.Event()
        self._timers: list[threading.Timer] = []
        self._closed = False
        now = self.clock.now()
        for m in models:
            m.advance(now)
        self._thread = threading.Thread(target=self._run, name=f"stepfoc-can-sim {channel}", daemon=True)
        self._thread.start()

    @property
    def lock(self) -> threading.Lock:
        """Hold it to read or change the models while the server runs (as the UART server's ``lock``)."""
        return self._lock

    @property
    def model(self) -> MsgModel:
        return self.models[0]

    @property
    def url(self) -> str:
        return f"stepfoc+can://{self.interface}/{self.channel}?node={self.models[0].node}"

    def urls(self) -> list[str]:
        return [f"stepfoc+can://{self.interface}/{self.channel}?node={m.node}" for m in self.models]

    def now(self) -> float:
        return self.clock.now()

    # ------------------------------------------------------------------------------------------ thread

    def _run(self) -> None:
        try:
            while not self._stop.is_set():
                try:
                    msg = self.bus.recv(timeout=self._wait())
                except can.CanError as exc:
                    # The host's interface went down (ip link set vcan0 down): a device on the wire would
                    # not notice, so the simulated one keeps running and hears nothing until it is up.
                    if not is_link_failure(exc):
                        raise
                    msg = None
                with self._lock:
                    now = self.clock.now()
                    out: list[CanFrame] = []
                    for m in self.models:
                        m.advance(now)
                    if msg is not None and not msg.is_error_frame and not msg.is_extended_id:
                        for m in list(self.models):
                            out.extend(
                                m.handle_frame(msg.arbitration_id, bytes(msg.data), msg.is_remote_frame, now)
                            )
                    beats = [f for m in self.models for f in m.due_frames(now)]
                for frame in out:
                    self._reply(frame)
                if not self.faults.silent:
                    for frame in beats:
                        self._send(frame)
        except BaseException as exc:  # noqa: BLE001 - kept for the test that asks why the server stopped
            if not self._stop.is_set():
                self.error = exc

    def _wait(self) -> float:
        due = [t for t in (m.next_event() for m in self.models) if t is not None]
        if not due:
            return _POLL_S
        return max(0.0, min(_POLL_S, self.clock.wall(min(due) - self.clock.now())))

    def _reply(self, frame: CanFrame) -> None:
        if self.faults.silent:
            return
        out, delay = apply_fault(
            frame,
            self.faults.take(),
            corrupt=lambda f: CanFrame(f.arbitration_id, flip_last_byte(f.data), False),
            truncate=lambda f: CanFrame(f.arbitration_id, first_half(f.data), False),
            error_bit=lambda f: CanFrame(f.arbitration_id | 1, f.data, False),
        )
        for reply in out:
            if delay:
                timer = threading.Timer(delay, self._send, (reply,))
                timer.daemon = True
                self._timers.append(timer)
                timer.start()
            else:
                self._send(reply)

    def _send(self, frame: CanFrame) -> None:
        if self._closed:
            return
        if not 0 <= frame.arbitration_id <= 0x7FF:  # the simulator speaks standard frames only
            raise ValueError(f"identifier 0x{frame.arbitration_id:X} does not fit an 11-bit standard frame")
        msg = standard_message(frame.arbitration_id, frame.data, frame.remote)
        try:
            self.bus.send(msg, timeout=0.5)
        except can.CanError as exc:
            if not self._stop.is_set() and not is_link_failure(exc):
                raise  # a frame lost on a down interface is lost on the wire too

    # ------------------------------------------------------------------------------------------ control

    def close(self) -> None:
        """Stop the thread and release the bus (only if this server opened it). Idempotent."""
        if self._closed:
            return
        self._stop.set()
        self._thread.join(timeout=2.0)
        self._closed = True
        for t in self._timers:
            t.cancel()
        if self._own_bus:
            self.bus.shutdown()


def serve_can(
    models: Iterable[MsgModel] | MsgModel | None = None,
    listen: str = "can://virtual/stepfoc-sim",
    *,
    bus: can.BusABC | None = None,
    time_scale: float = 1.0,
    clock: SimClock | None = None,
) -> CanSimServer:
    """Start a CAN simulator. ``listen``: ``can://INTERFACE/CHANNEL[?node=N&bitrate=B]``; ``node`` renumbers a
    single model (or creates one when ``models`` is None). ``bus`` (optional) is used instead of opening one
    and is left open on close. ``clock`` (optional) replaces the
    scaled clock (a test that prepared a model in simulated time starts the clock where the model is)."""
    interface, channel, params = parse_can_url(listen)
    if models is None:
        model_list = [MsgModel(node=int(params.get("node", 0)))]
    elif isinstance(models, MsgModel):
        model_list = [models]
    else:
        model_list = list(models)
    if not model_list:
        raise ValueError("serve_can needs at least one model")
    if "node" in params and len(model_list) == 1:
        model_list[0].node = model_list[0].saved_node = int(params["node"])
    nodes = [m.node for m in model_list]
    bad = [n for n in nodes if not 0 <= n <= MAX_NODE]
    if bad:  # node << 7 would not fit the 11-bit standard identifier of docs/protocols.md §2
        raise ValueError(f"node ids {bad} do not fit an 11-bit standard identifier (0..{MAX_NODE})")
    if len(set(nodes)) != len(nodes):
        raise ValueError(f"two simulated nodes share a node id: {nodes}")
    own = bus is None
    if bus is None:
        kwargs: dict[str, Any] = {}
        if interface != "virtual":
            kwargs["bitrate"] = int(params.get("bitrate", DEFAULT_BITRATE))
        if interface == "udp_multicast":
            kwargs.pop("bitrate")
            if "port" in params:
                kwargs["port"] = int(params["port"])
        try:
            bus = can.Bus(interface=interface, channel=channel, **kwargs)
        except (can.CanError, OSError, ValueError, ImportError) as exc:
            raise ConnectionLost(f"cannot open the CAN bus: {exc}", device=listen, command="serve") from exc
    try:
        return CanSimServer(
            model_list,
            bus,
            interface=interface,
            channel=channel,
            own_bus=own,
            time_scale=time_scale,
            clock=clock,
        )
    except BaseException:  # whatever the server refused, a bus it opened must not leak
        if own:
            bus.shutdown()
        raise
