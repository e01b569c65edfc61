"""The Zenoh side of a ``zenoh://`` device: the session, its queries, the heartbeat, the server's liveliness.

One :class:`ServedLink` per :class:`~grippers.remote.client.RemoteDevice`. Each call is one Zenoh query
bounded by a timeout: a vanished server is a ``ConnectionLost`` within that bound (at once when its token goes
away), never a hang. It is also the device's ``liveness`` feature (grippers/device.py ``Liveness``: ``error``,
``add_listener``) and its ``state_source`` feature (``subscribe``: a subscription to the published states, not
polling).
"""

from __future__ import annotations

import queue
import threading
import time
import uuid
from collections.abc import Callable
from typing import Any

from ..device import DeviceContext
from ..errors import AccessDenied, CommandFailed, ConnectionLost, GripperError, GripperTimeout, ProtocolError
from ..states import GripperState
from . import payloads, protocol
from .holder import LeaseHolder, LossListeners
from .session import import_zenoh, open_session
from .stream import SubscribedStream

HEARTBEATS_PER_LEASE = 4  # heartbeats per server lease timeout, as Zenoh's own keep-alives per link lease
RELEASE_AT_CLOSE_S = 1.0  # how long close() waits for the server to take its lease back
_END = object()


class ServedLink:
    """The session to the server serving ``name``; holds the control lease by its secret (holder.py)."""

    def __init__(self, url: str, name: str, config: Any, *, timeout: float, label: str) -> None:
        self.url = url
        self.served_name = name
        self.timeout = timeout
        self.client_id = uuid.uuid4().hex
        self.label = label
        self.context = DeviceContext(name=url)  # the device's, once a gripper took it
        self.lost: GripperError | None = None
        self.holder = LeaseHolder(name, self.client_id, label, url)  # the lease secret (holder.py)
        self._listeners = LossListeners()
        self.session = open_session(config, url)
        self._entities: list[Any] = []
        self._queriers: dict[str, Any] = {}
        self._streams: list[SubscribedStream] = []
        self._beating = threading.Event()
        self._heartbeat: threading.Thread | None = None
        self._lease_s = 1.0  # the server's lease timeout (its info), once known
        self._alive_at = time.monotonic()  # the heartbeat thread's last turn
        self._silent_at = -1.0  # when it last found this process had stood still longer than the lease
        self._last_publication = time.monotonic()  # when a stream last heard the server publish
        self._probing = False
        try:
            # The token first: the server sees it before our first command (a free lease goes to a client
            # whose token it can watch).
            live = self.session.liveliness()
            self._entities.append(live.declare_token(protocol.client_key(name, self.client_id)))
            self.info_doc = self.query(protocol.info_key(name), b"", "info", timeout, device=url)
            zenoh = import_zenoh()
            self._entities.append(
                live.declare_subscriber(
                    protocol.token_key(name),
                    zenoh.handlers.Callback(self._on_token, indirect=False),
                    history=False,
                )
            )
            self._start_heartbeat(self.info_doc.get("lease_timeout"))
        except BaseException:
            self._beating.set()
            self.session.close()
            raise

    @property
    def name(self) -> str:
        return self.context.name

    # -- the liveness feature--------------------------------------------------------------------------------

    @property
    def error(self) -> GripperError | None:
        return self.lost

    def add_listener(self, callback: Callable[[bool], Any]) -> Callable[[], None]:
        return self._listeners.add(callback)

    def _start_heartbeat(self, lease_timeout: Any) -> None:
        """Show life to the server while this client holds the lease: the server frees the lease of a holder
        not heard from within its --lease-timeout and stops what it set moving, whatever Zenoh link lease we
        announced. A heartbeat is a ``control heartbeat`` query with the secret (a query reaches the server's
        queryable only; a publication would show the secret to every subscriber). A frozen process (SIGSTOP,
        a debugger) stops beating with everything else, which is the point."""
        lease = lease_timeout if isinstance(lease_timeout, int | float) and lease_timeout > 0 else 1.0
        self._lease_s = float(lease)
        period = float(lease) / HEARTBEATS_PER_LEASE

        self._alive_at = time.monotonic()

        def beat() -> None:
            while not self._beating.wait(period):
                now = time.monotonic()
                if now - self._alive_at > lease:  # this process stood still longer than the server's lease
                    self._silent_at = now
                self._alive_at = now
                try:
                    if self.lost is None:
                        self.holder.beat(self.session, period)
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
        if not self._streams or self.lost is not None or self._probing:
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
                self.declare_lost(f"the server serving {self.served_name!r} stopped answering")

        self.session.get(
            protocol.info_key(self.served_name),
            zenoh.handlers.Callback(on_reply, on_done, indirect=False),
            timeout=self.timeout,
        )

    def _on_token(self, sample: Any) -> None:
        zenoh = import_zenoh()
        if sample.kind != zenoh.SampleKind.DELETE:
            return
        self.declare_lost(
            f"the server withdrew {self.served_name!r} (server stopped or gripper disconnected)"
        )

    def declare_lost(self, why: str) -> None:
        """Calls fail with ConnectionLost from now on. Without reconnect=true that is final, as on every
        other transport: ``connected`` is False, the listeners are told (the gripper ends servoing, then the
        ``on_connection`` callbacks), streams end with the error. With it, the link watch
        (grippers/reconnect.py) ends servoing, tells the callbacks and brings the server back; motion
        resumes only by a new command."""
        if self.lost is not None or self.context.closed():
            return
        self.lost = ConnectionLost(why, device=self.name)
        if not self.context.reconnects():
            for s in list(self._streams):
                s.fail(self.lost)
            self._listeners.tell()

    def check(self, command: str) -> None:
        if self.lost is not None:
            raise ConnectionLost(self.lost.message, device=self.name, command=command)

    # -- queries ------------------------------------------------------------------------------------------

    def query(
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
        secret = self.holder.secret
        replies: queue.Queue[Any] = queue.Queue()
        handler = zenoh.handlers.Callback(replies.put, lambda: replies.put(_END), indirect=False)
        started = time.monotonic()
        self.session.get(
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
                if self.lost is not None:
                    raise ConnectionLost(self.lost.message, device=dev, command=command)
                elapsed = time.monotonic() - started
                if pending and elapsed < timeout - 0.05:
                    if device is None and self._silent_since(started):
                        # This process did not run for longer than the server's lease (frozen, SIGSTOP, a
                        # debugger): the server freed the lease, stopped the motion and dropped the query.
                        # Said so, not "went away" (issue 43 §6). The next command takes a new lease.
                        self.holder.secret = None
                        raise CommandFailed(
                            "the motion ended without its result while the server still serves: this client "
                            "was not heard from within the server's lease (frozen or cut off), so the server "
                            "stopped what it had set moving and freed the lease",
                            device=dev,
                            command=command,
                        )
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
                    self.holder.refused(error, secret)  # AccessDenied: that lease has ended
                raise error
            data = reply.ok.payload.to_bytes()
            if command in ("info", "state"):
                return protocol.decode_json(data, command)
            status, result, granted = protocol.parse_reply(data, command)
            self.holder.granted(granted)
            if status == protocol.DONE:
                return result
            pending = True
            if on_pending is not None:
                on_pending()

    def _server_answers(self) -> bool:
        """Whether the server answers its info key now (bounded by the exchange timeout)."""
        try:
            self.query(protocol.info_key(self.served_name), b"", "info", self.timeout, device=self.url)
        except GripperError:
            return False
        return True

    def _silent_since(self, started: float) -> bool:
        """Whether this process stood still longer than the server's lease since ``started`` (seen by the
        heartbeat thread's turns, whichever thread wakes first after a SIGCONT)."""
        return self._silent_at >= started or time.monotonic() - self._alive_at > self._lease_s

    def control_query(self, key: str, payload: bytes, command: str, timeout: float) -> Any:
        """A lease query (holder.py): its silence is not a lost link (``device`` given)."""
        return self.query(key, payload, command, timeout, device=key)

    def _no_answer(self, why: str, ours: bool) -> None:
        """A query on our gripper's keys that no server answered: the link is lost (final without
        reconnect=true), not a slow reply to try again behind the user's back."""
        if ours:
            self.declare_lost(why)

    def call(self, command: str, args: dict[str, Any] | None = None, timeout: float | None = None) -> Any:
        self.check(command)
        payload = self.holder.request(args or {})
        wait = self.timeout if timeout is None else timeout + self.timeout
        return self.query(protocol.command_key(self.served_name, command), payload, command, wait)

    def command(self, verb: str, bound: float | None = None, /, **args: Any) -> Any:
        """Send a served verb with exactly the arguments grippers/commands.py's table says it takes (the
        server refuses anything else): the device's calls are checked against the table on every call.
        ``bound``: how long the command may take beyond the exchange timeout (a motion's timeout)."""
        expected = protocol.COMMANDS[verb].args
        if set(args) != set(expected):
            raise ProtocolError(
                f"the client sends {sorted(args)}, the command table says {sorted(expected)}", command=verb
            )
        return self.call(verb, args, bound)

    def read(self, key: str, command: str) -> Any:
        """A read (state): Zenoh's own channel, the fastest path; bounded by the query's timeout, which is
        also how long Ctrl-C may wait (a motion waits on an interruptible queue instead, see query)."""
        self.check(command)
        querier = self._queriers.get(key)
        if querier is None:  # declared once: Zenoh resolves the key and its routes once, not per call
            querier = self._queriers[key] = self.session.declare_querier(key, timeout=self.timeout)
            self._entities.append(querier)
        started = time.monotonic()
        for reply in querier.get():
            if reply.err is not None:
                if protocol.is_query_timeout(reply.err.payload.to_bytes()):
                    break  # Zenoh's own "no reply within the timeout": no answer (below)
                raise protocol.decode_error(reply.err.payload.to_bytes(), command, self.name)
            return protocol.decode_json(reply.ok.payload.to_bytes(), command)
        self.check(command)
        why = (
            f"no answer from a server serving {self.served_name!r} after {time.monotonic() - started:.1f} s "
            f"(timeout {self.timeout:g} s)"
        )
        self.declare_lost(why)
        raise ConnectionLost(why, device=self.name, command=command)

    # -- the state_source feature: a subscription ----------------------------------------------------------

    def subscribe(
        self,
        rate_hz: float,
        callback: Callable[[GripperState], Any] | None,
        on_close: Callable[[Any], None],
    ) -> SubscribedStream:
        """The served states as they are published (at most ``rate_hz`` of them a second)."""
        zenoh = import_zenoh()
        self.check("stream")

        def closed(s: SubscribedStream) -> None:
            if s in self._streams:
                self._streams.remove(s)
            on_close(s)

        s = SubscribedStream(
            lambda data: payloads.state_from(protocol.decode_json(data, "stream"), self.name),
            rate_hz,
            callback,
            on_close=closed,
        )
        sub = self.session.declare_subscriber(
            protocol.state_key(self.served_name),
            zenoh.handlers.Callback(lambda sample: self._feed(s, sample), indirect=False),
        )
        s.attach(sub)
        if not self._streams:
            self._last_publication = time.monotonic()  # silence is counted from now
        self._streams.append(s)
        return s

    def _feed(self, s: SubscribedStream, sample: Any) -> None:
        self._last_publication = time.monotonic()
        s.feed(sample.payload.to_bytes())

    def close(self) -> None:
        if self.lost is None:
            # Give the lease back before the token goes: a normal close is not a vanished holder (the
            # server's deadman would log it as one, and stop a servoing that is meant to settle).
            self.holder.give_back(self.control_query, RELEASE_AT_CLOSE_S)
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
            self.session.close()
        except Exception:
            pass
