"""``zenoh://NAME?connect=tcp/HOST:7447``: a served gripper behind the ordinary :class:`Gripper` API.

Limits come from the served info and are checked here before anything is sent (and again by the server);
errors arrive as a class name and are raised as the same class; ``stream()`` is a Zenoh subscription to the
published states, not polling. Each call is one Zenoh query bounded by a timeout: a vanished server is a
``ConnectionLost`` within that bound (at once when its token goes away), never a hang.
"""

from __future__ import annotations

import os
import queue
import socket
import threading
import time
import uuid
from collections.abc import Callable
from typing import Any

from ..errors import AccessDenied, ConnectionLost, GripperError, GripperTimeout, ProtocolError, URLError
from ..gripper import Capability, DeviceInfo, GraspResult, Gripper, GripperState, MotionResult
from ..profiles import Limits, ProfileBase, parse_profile
from . import payloads, protocol
from .holder import LeaseHolder, LossListeners
from .session import check_endpoints, import_zenoh, make_config, open_session
from .stream import SubscribedStream

DEFAULT_TIMEOUT = 2.0
DEFAULT_LINK_LEASE = 1.0  # s; matches the server's default --lease-timeout
HEARTBEATS_PER_LEASE = 4  # heartbeats per server lease timeout, as Zenoh's own keep-alives per link lease
MAX_LABEL = 256  # protocol.parse_request's bound on a request's label
RELEASE_AT_CLOSE_S = 1.0  # how long close() waits for the server to take its lease back
_END = object()


class ZenohBackend:
    """The ``zenoh`` family of the backend table: no profile of its own, the served one is used."""

    family = "zenoh"
    profile_model = None

    def open(self, url: Any, profile: ProfileBase | None, settings: Any) -> RemoteGripper:
        name = url.channel or ""
        if not name:
            raise URLError(f"{url.url}: name the served gripper (zenoh://NAME?connect=tcp/HOST:7447)")
        try:
            protocol.check_name(name)
        except ValueError as exc:
            raise URLError(f"{url.url}: {exc}") from None
        connect = check_endpoints(
            [e for e in settings.str("connect", "").split(",") if e], f"{url.url}: connect"
        )
        config_file = settings.str("zenoh_config", None)
        scout = settings.bool("scout", False)
        if not (connect or config_file or scout):
            raise URLError(
                f"{url.url}: say where the server is: ?connect=tcp/HOST:7447 (or zenoh_config=, scout=1)"
            )
        config = make_config(
            mode=settings.str("mode", "client"),
            listen=[],
            connect=connect,
            config_file=config_file,
            scout=scout,
            # The link lease this session announces: how long the server waits on a silent link before our
            # token (and the control lease with it) goes away. Zenoh's default is 10 s.
            lease_s=settings.positive("lease", DEFAULT_LINK_LEASE),
        )
        timeout = settings.positive("timeout", DEFAULT_TIMEOUT)
        label = settings.str("label", f"{socket.gethostname()} pid {os.getpid()}")
        if len(label) > MAX_LABEL:  # the server refuses such a request: said at open, not at every command
            raise URLError(f"{url.url}: label is {len(label)} characters long; at most {MAX_LABEL}")
        settings.check()  # a misspelt setting is refused before the session opens
        return RemoteGripper(url.url, name, config, timeout=timeout, label=label, profile=profile)


class RemoteGripper(Gripper):
    """A gripper served by ``grippers serve``; holds the control lease by its secret (docs/remote.md).

    The secret arrives in the reply to the request that took the lease and goes with every later command
    and every heartbeat; it is dropped when the server says the lease has ended (AccessDenied to a request
    that carried it), so the next command takes a free lease anew: never a silent re-take of a lease lost
    behind the user's back (a lost link is final without reconnect=true, and ends servoing with it)."""

    def __init__(
        self,
        url: str,
        name: str,
        config: Any,
        *,
        timeout: float,
        label: str,
        profile: ProfileBase | None = None,
    ) -> None:
        self.served_name = name
        self.client_id = uuid.uuid4().hex
        self.label = label
        self._lost: GripperError | None = None
        self._holder = LeaseHolder(name, self.client_id, label, url)  # the lease secret (holder.py)
        self._loss_listeners = LossListeners()
        self._session = open_session(config, url)
        self._entities: list[Any] = []
        self._queriers: dict[str, Any] = {}
        self._remote_streams: list[SubscribedStream] = []
        self._beating = threading.Event()
        self._heartbeat: threading.Thread | None = None
        self._last_publication = time.monotonic()  # when a stream last heard the server publish
        self._probing = False
        try:
            # The token first: the server sees it before our first command (a free lease goes to a client
            # whose token it can watch).
            live = self._session.liveliness()
            self._entities.append(live.declare_token(protocol.client_key(name, self.client_id)))
            doc = self._query(protocol.info_key(name), b"", "info", timeout, device=url)
            # Read with the family's model if installed, else as the generic profile (no vendor code needed).
            served = parse_profile(doc["profile_data"], f"{url} (served profile)", generic=True)
            if profile is not None and profile.name != served.name:
                raise URLError(f"{url}: serves {served.name!r}, not the profile {profile.name!r} asked for")
            super().__init__(served, url, timeout=timeout)
            self.limits = Limits.model_validate(doc["limits"])  # the served, possibly device-narrowed, limits
            self.capabilities = frozenset(Capability(c) for c in doc["capabilities"] if c in _CAPS)
            self._info_doc = doc
            self._profile_assumed = bool(doc.get("profile_assumed", False))  # warned by grippers.open
            zenoh = import_zenoh()
            self._entities.append(
                live.declare_subscriber(
                    protocol.token_key(name),
                    zenoh.handlers.Callback(self._on_token, indirect=False),
                    history=False,
                )
            )
            self._start_heartbeat(doc.get("lease_timeout"))
        except BaseException:
            self._beating.set()
            self._session.close()
            raise

    # -- plumbing -----------------------------------------------------------------------------------------

    @property
    def driver(self) -> Any:
        """The Zenoh session underneath (vendor extras stay on the serving machine)."""
        return self._session

    def _start_heartbeat(self, lease_timeout: Any) -> None:
        """Show life to the server while this client holds the lease: the server frees the lease of a holder
        not heard from within its --lease-timeout and stops what it set moving, whatever Zenoh link lease we
        announced. A heartbeat is a ``control heartbeat`` query with the secret (a query reaches the server's
        queryable only; a publication would show the secret to every subscriber). A frozen process (SIGSTOP,
        a debugger) stops beating with everything else, which is the point."""
        lease = lease_timeout if isinstance(lease_timeout, int | float) and lease_timeout > 0 else 1.0
        period = float(lease) / HEARTBEATS_PER_LEASE

        def beat() -> None:
            while not self._beating.wait(period):
                try:
                    if self._lost is None:
                        self._holder.beat(self._session, period)
                    self._watch_publications(float(lease))
                except Exception:  # the session is closing: close() ends this loop next
                    pass

        self._heartbeat = threading.Thread(target=beat, name=f"grippers-heartbeat {self.served_name}")
        self._heartbeat.daemon = True
        self._heartbeat.start()

    def _watch_publications(self, lease: float) -> None:
        """A stream waits on publications; when they stop for longer than the server's lease, ask the server
        (without blocking this thread) whether it is still there. A killed or frozen server does not always
        withdraw its token where we can see it (a client-mode session losing its only link is told nothing),
        and a stream must end with ConnectionLost then, not with GripperTimeout (issue 23 §2)."""
        if not self._remote_streams or self._lost is not None or self._probing:
            return
        if time.monotonic() - self._last_publication <= lease:
            return
        zenoh = import_zenoh()
        answered: list[bool] = []
        self._probing = True

        def on_reply(reply: Any) -> None:
            if reply.ok is not None:
                answered.append(True)
                self._last_publication = time.monotonic()  # a slow --rate, not a dead server

        def on_done() -> None:
            self._probing = False
            if not answered:
                self._declare_lost(f"the server serving {self.served_name!r} stopped answering")

        self._session.get(
            protocol.info_key(self.served_name),
            zenoh.handlers.Callback(on_reply, on_done, indirect=False),
            timeout=self.timeout,
        )

    def _on_token(self, sample: Any) -> None:
        zenoh = import_zenoh()
        if sample.kind != zenoh.SampleKind.DELETE:
            return
        self._declare_lost(
            f"the server withdrew {self.served_name!r} (server stopped or gripper disconnected)"
        )

    def _declare_lost(self, why: str) -> None:
        """Calls fail with ConnectionLost from now on. Without reconnect=true that is final, as on every
        other transport: ``connected`` is False, ``on_connection`` callbacks are told, servoing ends,
        streams end with the error, and every call raises until the gripper is reopened. With it, the
        link watch (grippers/reconnect.py) ends servoing, tells the callbacks and brings the server back;
        motion resumes only by a new command."""
        if self._lost is not None or self._closed:
            return
        self._lost = ConnectionLost(why, device=self.name)
        if self._watch is None:
            for s in list(self._remote_streams):
                s.fail(self._lost)
            self._loss_listeners.tell(lambda: self._end_servo(stop_device=False))

    @property
    def connected(self) -> bool:
        """False once the server is lost (final without reconnect=true) or after close()."""
        if self._lost is not None and self._watch is None:
            return False
        return super().connected

    def on_connection(self, callback: Callable[[bool], Any]) -> Callable[[], None]:
        """As on every gripper; without reconnect=true a lost server is reported (once), as close() is."""
        if self._watch is not None:
            return super().on_connection(callback)
        return self._loss_listeners.add(callback, super().on_connection)

    def _query(
        self,
        key: str,
        payload: bytes,
        command: str,
        timeout: float,
        *,
        device: str | None = None,
        on_pending: Callable[[], None] | None = None,
    ) -> Any:
        """One query: every reply is handled here; bounded by ``timeout`` plus the exchange timeout."""
        zenoh = import_zenoh()
        dev = device or self.name
        secret = self._holder.secret
        replies: queue.Queue[Any] = queue.Queue()
        handler = zenoh.handlers.Callback(replies.put, lambda: replies.put(_END), indirect=False)
        started = time.monotonic()
        self._session.get(
            key,
            handler,
            payload=payload or None,
            consolidation=zenoh.ConsolidationMode.NONE,
            timeout=timeout,
        )
        deadline = started + timeout + 0.5  # Zenoh ends the query at ``timeout``; this is a backstop
        pending = False
        while True:
            try:
                reply = replies.get(timeout=max(0.0, deadline - time.monotonic()))
            except queue.Empty:
                reply = _END
            if (
                reply is not _END
                and reply.err is not None
                and protocol.is_query_timeout(reply.err.payload.to_bytes())
            ):
                reply = _END  # Zenoh's own "no reply within the timeout"
            if reply is _END:
                if self._lost is not None:
                    raise ConnectionLost(self._lost.message, device=dev, command=command)
                elapsed = time.monotonic() - started
                if pending and elapsed < timeout - 0.05:
                    self._no_answer("the server went away mid-motion", device is None)
                    raise ConnectionLost("the server went away mid-motion", device=dev, command=command)
                if pending:
                    raise GripperTimeout(f"no result within {timeout:g} s", device=dev, command=command)
                if device is None and elapsed < timeout - 0.05 and self._server_answers():
                    # Ended at once while the server answers its info: Zenoh itself refused to route the
                    # command (access control, docs/remote.md "Security"), the link is fine.
                    raise AccessDenied(
                        f"the Zenoh network refused {command} (no route to the server's command: its access "
                        "control does not let this client's identity send it)",
                        device=dev,
                        command=command,
                    )
                # The time it really took: Zenoh ends a query early when it has no route to a queryable.
                why = (
                    f"no answer from a server serving {self.served_name if device is None else key!r} "
                    f"after {elapsed:.1f} s (timeout {timeout:g} s)"
                )
                self._no_answer(why, device is None)
                raise ConnectionLost(why, device=dev, command=command)
            if reply.err is not None:
                error = protocol.decode_error(reply.err.payload.to_bytes(), command, dev)
                if payload:
                    self._holder.refused(error, secret)  # AccessDenied: that lease has ended
                raise error
            data = reply.ok.payload.to_bytes()
            if command in ("info", "state"):
                return protocol.decode_json(data, command)
            status, result, granted = protocol.parse_reply(data, command)
            self._holder.granted(granted)
            if status == protocol.DONE:
                return result
            pending = True
            if on_pending is not None:
                on_pending()

    def _server_answers(self) -> bool:
        """Whether the server answers its info key now (bounded by the exchange timeout)."""
        try:
            self._query(protocol.info_key(self.served_name), b"", "info", self.timeout, device=self.url)
        except GripperError:
            return False
        return True

    def _control_query(self, key: str, payload: bytes, command: str, timeout: float) -> Any:
        """A lease query (holder.py): its silence is not a lost link (``device`` given)."""
        return self._query(key, payload, command, timeout, device=key)

    def _no_answer(self, why: str, ours: bool) -> None:
        """A query on our gripper's keys that no server answered: the link is lost (final without
        reconnect=true), not a slow reply to try again behind the user's back."""
        if ours:
            self._declare_lost(why)

    def _call(self, command: str, args: dict[str, Any] | None = None, timeout: float | None = None) -> Any:
        if self._lost is not None:
            raise ConnectionLost(self._lost.message, device=self.name, command=command)
        payload = self._holder.request(args or {})
        wait = self.timeout if timeout is None else timeout + self.timeout
        return self._query(protocol.command_key(self.served_name, command), payload, command, wait)

    def _command(self, verb: str, bound: float | None = None, /, **args: Any) -> Any:
        """Send a served verb with exactly the arguments grippers/commands.py's table says it takes (the
        server refuses anything else): the stubs below are checked against the table on every call.
        ``bound``: how long the command may take beyond the exchange timeout (a motion's timeout)."""
        expected = protocol.COMMANDS[verb].args
        if set(args) != set(expected):
            raise ProtocolError(
                f"the client sends {sorted(args)}, the command table says {sorted(expected)}", command=verb
            )
        return self._call(verb, args, bound)

    def _check_motion(self, command: str) -> None:
        if self._lost is not None and self._watch is None and not self._closed:
            raise ConnectionLost(self._lost.message, device=self.name, command=command)
        if self._fast_stopped and not self._closed:
            # Another client may have acknowledged the fast stop: the served state is the truth (state()
            # takes its faults over), and the server refuses motion itself while a fast stop is active.
            try:
                self.state()
            except GripperError:
                pass
        super()._check_motion(command)

    # -- the backend primitives ---------------------------------------------------------------------------

    def _home(self, timeout: float) -> None:
        self._command("home", timeout, timeout=timeout)

    def _move(self, width: float, speed: float, timeout: float) -> MotionResult:
        doc = self._command("move", timeout, width=width, speed=speed, timeout=timeout)
        return payloads.motion_from(doc, self.name, "move")

    def _grasp(self, width: float, speed: float, force: float, timeout: float) -> GraspResult:
        doc = self._command("grasp", timeout, width=width, speed=speed, force=force, timeout=timeout)
        return payloads.grasp_from(doc, self.name)

    def _servo_begin(self) -> None:
        """Nothing to prepare here: the server's gripper begins servoing with the first target it takes."""

    def _servo(self, target: Any) -> bool:
        # One query per target, from the servo thread only (so targets arrive in order); targets that come
        # while one is in flight are coalesced by the ServoLoop: latest wins here, and again on the server.
        # The server answers once its gripper's own slot holds the target (limits and lease checked there).
        self._command("servo", width=target.width, speed=target.speed, force=target.force)
        return True

    def _release(self, width: float, speed: float, timeout: float) -> MotionResult:
        doc = self._command("release", timeout, width=width, speed=speed, timeout=timeout)
        return payloads.motion_from(doc, self.name, "release")

    def _stop(self) -> None:
        self._command("stop")

    def _fast_stop(self) -> None:
        self._command("fast_stop")

    def _acknowledge(self) -> None:
        self._command("acknowledge")

    def _state(self) -> GripperState:
        if self._lost is not None:
            raise ConnectionLost(self._lost.message, device=self.name, command="state")
        return payloads.state_from(self._read(protocol.state_key(self.served_name), "state"), self.name)[1]

    def _read(self, key: str, command: str) -> Any:
        """A read (state): Zenoh's own channel, the fastest path; bounded by the query's timeout, which is
        also how long Ctrl-C may wait (a motion waits on an interruptible queue instead, see _query)."""
        querier = self._queriers.get(key)
        if querier is None:  # declared once: Zenoh resolves the key and its routes once, not per call
            querier = self._queriers[key] = self._session.declare_querier(key, timeout=self.timeout)
            self._entities.append(querier)
        started = time.monotonic()
        for reply in querier.get():
            if reply.err is not None:
                if protocol.is_query_timeout(reply.err.payload.to_bytes()):
                    break  # Zenoh's own "no reply within the timeout": no answer (below)
                raise protocol.decode_error(reply.err.payload.to_bytes(), command, self.name)
            return protocol.decode_json(reply.ok.payload.to_bytes(), command)
        if self._lost is not None:
            raise ConnectionLost(self._lost.message, device=self.name, command=command)
        why = (
            f"no answer from a server serving {self.served_name!r} after {time.monotonic() - started:.1f} s "
            f"(timeout {self.timeout:g} s)"
        )
        self._declare_lost(why)
        raise ConnectionLost(why, device=self.name, command=command)

    # -- reconnect=true (grippers/reconnect.py): the Zenoh session re-establishes its links by itself (its
    # connect retries); the served gripper is back when a server answers for it again. --------------------

    def _link_alive(self) -> bool:
        return self._lost is None  # the server withdrew the gripper's token; a silent one: the heartbeat

    def _reconnect(self) -> None:
        # Proof, not a flag: an info query that a server answers (ConnectionLost within the timeout if none).
        doc = self._query(protocol.info_key(self.served_name), b"", "info", self.timeout)
        self.limits = Limits.model_validate(doc["limits"])  # a restarted device may report other limits
        self._info_doc = doc
        self._lost = None
        # The lease ends with the outage: given back if the server still keeps it for us, so that motion
        # resumes only by a new command, which takes a fresh lease (issue 31 §2).
        self._holder.give_back(self._control_query, self.timeout)

    def _info(self) -> DeviceInfo:
        doc = self._query(protocol.info_key(self.served_name), b"", "info", self.timeout)
        return payloads.info_from(doc, self.url, self.name)

    def _temperature(self) -> float:
        value = self._command("temperature")
        if isinstance(value, bool) or not isinstance(value, int | float):
            raise ProtocolError(
                f"temperature is not a number: {value!r}", device=self.name, command="temperature"
            )
        return float(value)

    def _set_soft_limits(self, min_width: float | None, max_width: float | None) -> None:
        if min_width is None or max_width is None:
            self._command("clear_soft_limits")
        else:
            self._command("set_soft_limits", min_width=min_width, max_width=max_width)

    def _device_tag(self, tag: str | None) -> str:
        if tag is None:
            return str(self._command("device_tag"))
        self._command("set_device_tag", tag=tag)
        return tag

    # -- the control lease --------------------------------------------------------------------------------

    def control(self) -> _Control:
        """``with g.control():`` holds the control lease (AccessDenied if another client has it) and frees
        it at the end; without it, the first motion command takes the lease and keeps it until close()."""
        return _Control(self)

    def acquire_control(self) -> None:
        self._check_open("control")
        self._call("control", {"action": "acquire"})

    def release_control(self) -> None:
        self._check_open("control")
        self._call("control", {"action": "release"})
        self._holder.secret = None

    # -- streams: a subscription ----------------------------------------------------------------------------

    def stream(  # type: ignore[override]  # the same interface, fed by a subscription (stream.py)
        self, rate_hz: float = 50.0, callback: Callable[[GripperState], Any] | None = None
    ) -> SubscribedStream:
        """The served states as they are published (at most ``rate_hz`` of them a second)."""
        zenoh = import_zenoh()
        with self._lock:
            self._check_open("stream")
            if self._lost is not None:
                raise ConnectionLost(self._lost.message, device=self.name, command="stream")
            s = SubscribedStream(
                lambda data: payloads.state_from(protocol.decode_json(data, "stream"), self.name),
                rate_hz,
                callback,
                on_close=self._forget_remote_stream,
            )
            sub = self._session.declare_subscriber(
                protocol.state_key(self.served_name),
                zenoh.handlers.Callback(lambda sample: self._feed(s, sample), indirect=False),
            )
            s.attach(sub)
            if not self._remote_streams:
                self._last_publication = time.monotonic()  # silence is counted from now
            self._remote_streams.append(s)
            self._streams.append(s)  # type: ignore[arg-type]  # closed by Gripper.close() like any stream
        return s

    def _feed(self, s: SubscribedStream, sample: Any) -> None:
        self._last_publication = time.monotonic()
        s.feed(sample.payload.to_bytes())

    def _forget_remote_stream(self, s: SubscribedStream) -> None:
        with self._lock:
            if s in self._remote_streams:
                self._remote_streams.remove(s)
            if s in self._streams:
                self._streams.remove(s)  # type: ignore[arg-type]  # added as a StateStream (above)

    def _close(self) -> None:
        if self._lost is None:
            # Give the lease back before the token goes: a normal close is not a vanished holder (the
            # server's deadman would log it as one, and stop a servoing that is meant to settle).
            self._holder.give_back(self._control_query, RELEASE_AT_CLOSE_S)
        self._beating.set()
        if self._heartbeat is not None and self._heartbeat is not threading.current_thread():
            self._heartbeat.join(5.0)
        for entity in reversed(self._entities):
            try:
                entity.undeclare()
            except Exception:
                pass
        self._entities.clear()
        try:
            self._session.close()
        except Exception:
            pass


_CAPS = {c.value for c in Capability}


class _Control:
    def __init__(self, gripper: RemoteGripper) -> None:
        self.gripper = gripper

    def __enter__(self) -> RemoteGripper:
        self.gripper.acquire_control()
        return self.gripper

    def __exit__(self, *exc: object) -> None:
        if not self.gripper._closed and self.gripper._lost is None:
            try:
                self.gripper.release_control()
            except GripperError:
                pass
