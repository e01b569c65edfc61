"""``grippers serve``: open grippers, serve each one under ``grippers/<name>/…`` (docs/remote.md).

Threads, and why: Zenoh calls our callbacks on its own network threads (``indirect=False``: no extra Python
thread per queryable), which only hand the query over. Reads and settings run on a shared pool; stop and
fast_stop on a pool of their own so they never queue behind reads; each motion runs on its own thread,
which answers ``pending`` at once and the result when the motion ends. One publisher thread per gripper
reads the state at the rate, publishes it and watches the lease.
"""

from __future__ import annotations

import logging
import threading
import time
from concurrent.futures import ThreadPoolExecutor
from typing import Any

from .. import commands
from ..drivers.urls import zenoh_port
from ..errors import AccessDenied, CommandFailed, ConnectionLost, GripperError, ProtocolError
from ..gripper import Gripper
from . import payloads, protocol
from .discovery import refuse_duplicate
from .gate import Gate, Slot
from .session import DEFAULT_LISTEN, import_zenoh, make_config, open_session, own_locators

log = logging.getLogger("grippers.remote")  # serve's own lines: lost, back, lease changes (docs/remote.md)

CLOSE_JOIN_S = 5.0
RETRY_LOST_S = 1.0  # how often a lost gripper is tried again (a reconnect=true URL brings it back)
# The served verbs and the Gripper methods they call, with the arguments protocol.parse_request checked
# against the same table (grippers/commands.py): the dispatch is a look-up, not a copy of the table.
_VERBS = commands.served()
_URGENT = frozenset(verb for verb, c in _VERBS.items() if c.urgent)
_STOPS = frozenset(("stop", "fast_stop"))


class ServedGripper:
    """One gripper on the key space: its token, state publisher, queryables and control lease."""

    def __init__(self, server: Server, name: str, gripper: Gripper) -> None:
        self.server = server
        self.name = name
        self.gripper = gripper
        self.gate = Gate(name, server.lease_timeout)
        self.lease = self.gate.lease
        self._lease_lock = self.gate.lock
        self._pub_lock = threading.Lock()
        self._seq = 0
        self._latest: bytes | None = None
        self._lost: GripperError | None = None
        self._stop = threading.Event()
        self._kick = threading.Event()
        self._motions: dict[threading.Thread, str] = {}  # running motion -> the client that started it
        self._motions_lock = threading.Lock()
        self._servo_owner: str | None = None  # the client whose targets the gripper is servoing to
        # Stops received so far (counted on Zenoh's thread, as each arrives) and the order of the calls that
        # set the jaws moving against them: a stop wins over every request received before it.
        self._stops = 0
        self._stops_lock = threading.Lock()
        self._order = threading.Lock()
        # Clients whose servoing another client's stop ended: their targets are refused until they say they
        # know (a stop of their own, which a zenoh:// client's stop() sends, ``control acquire`` or a motion
        # command), so targets sent before the stop and received after it do not move the jaws either.
        self._servo_stopped: set[str] = set()
        self._declared: list[Any] = []
        self._token: Any = None
        self._info_base: dict[str, Any] = {}
        self._thread = threading.Thread(target=self._publish_loop, name=f"grippers-serve-{name}", daemon=True)

    # -- set-up and tear-down -----------------------------------------------------------------------------

    def start(self) -> None:
        zenoh = import_zenoh()
        session = self.server.session
        callback = zenoh.handlers.Callback
        refuse_duplicate(session, self.name)
        self._read_info()
        self._publisher = session.declare_publisher(protocol.state_key(self.name))
        self._declared.append(self._publisher)
        self._declared.append(
            session.declare_queryable(
                protocol.state_key(self.name), callback(self._on_state, indirect=False), complete=True
            )
        )
        self._declared.append(
            session.declare_queryable(
                protocol.info_key(self.name), callback(self._on_info, indirect=False), complete=True
            )
        )
        for command in protocol.COMMANDS:
            key = protocol.command_key(self.name, command)
            handler = callback(lambda q, c=command: self._on_command(q, c), indirect=False)
            self._declared.append(session.declare_queryable(key, handler, complete=True))
        self._declared.append(
            session.liveliness().declare_subscriber(
                protocol.all_clients_key(self.name), callback(self._on_client, indirect=False), history=True
            )
        )
        self._refresh()
        self._thread.start()
        self._token = session.liveliness().declare_token(protocol.token_key(self.name))

    def _read_info(self) -> None:
        info = self.gripper.info()
        caps = sorted(c.value for c in self.gripper.capabilities)
        profile_data = self.gripper.profile.model_dump(mode="json")
        self._info_base = payloads.info_doc(
            self.name,
            info,
            caps,
            profile_data,
            self.server.lease_timeout,
            profile_assumed=bool(getattr(self.gripper, "_profile_assumed", False)),
        )

    def close(self) -> None:
        self._stop.set()
        self._withdraw()
        if self._thread.is_alive():
            self._thread.join(CLOSE_JOIN_S)
        # Under the publishing lock: a motion thread that ends now (the stop below aborts it) publishes its
        # last state before this or not at all, never on an undeclared publisher (issue 43 §1: a thread
        # traceback "zenoh.ZError: Undeclared publisher" at SIGTERM).
        with self._pub_lock:
            for entity in self._declared:
                try:
                    entity.undeclare()
                except Exception:  # already undeclared with a closed session
                    pass
            self._declared.clear()
        with self._motions_lock:
            running = list(self._motions)
        if self._lost is None and self._moves(bool(running) or self._servo_owner is not None):
            # No one will see these motions end: a served gripper does not keep moving once unserved (a
            # motion waited on, a servoing, a motion whose wait timed out: issue 33 §1).
            self._servo_owner = None
            try:
                self.gripper.stop()
            except GripperError as exc:
                log.error("%s: stop at shutdown failed: %s", self.name, exc)
        for t in running:
            t.join(CLOSE_JOIN_S)

    def _withdraw(self) -> None:
        token, self._token = self._token, None
        if token is not None:
            try:
                token.undeclare()
            except Exception:
                pass

    # -- state ----------------------------------------------------------------------------------------------

    def _refresh(self) -> None:
        """Read, publish and cache one state; a lost gripper withdraws its token (clients: ConnectionLost)."""
        if self._lost is not None:
            return
        with self._pub_lock:
            try:
                state = self.gripper.state()
            except ConnectionLost as exc:
                self._lose(exc)
                return
            except GripperError as exc:  # one missed reading (a timeout): the next tick tries again
                log.warning("%s: state read failed: %s", self.name, exc)
                return
            self._seq += 1
            data = protocol.dumps(payloads.state_doc(state, self._seq))
            self._latest = data
            if self._stop.is_set():  # closing: the publisher is undeclared (under this lock) or about to be
                return
            self._publisher.put(data)

    def _lose(self, exc: GripperError) -> None:
        self._lost = ConnectionLost(f"the served gripper is gone: {exc.message}", device=self.name)
        log.error("%s: gripper lost (%s); withdrawn until it answers again", self.name, exc)
        self._withdraw()

    def _try_back(self) -> None:
        """A lost gripper that answers again (a reconnect=true URL, a device back on its link) is served
        again: its token comes back, so clients with reconnect=true count it back."""
        try:
            self.gripper.state()
            self._read_info()  # a device that came back may report other limits
        except GripperError:
            return
        self._lost = None
        self._refresh()
        if self._lost is None and not self._stop.is_set():
            self._token = self.server.session.liveliness().declare_token(protocol.token_key(self.name))
            log.warning("%s: gripper back; served again", self.name)

    def _publish_loop(self) -> None:
        period = 1.0 / self.server.rate
        next_at = time.monotonic()
        while not self._stop.is_set():
            if self._lost is not None:
                if self._stop.wait(RETRY_LOST_S):
                    return
                self._try_back()
                next_at = time.monotonic()
                continue
            self._refresh()
            with self._lease_lock:
                expired = self.lease.expired(time.monotonic())
            if expired is not None:
                log.warning(
                    "%s: client %s not heard from within %g s; lease freed",
                    self.name,
                    expired,
                    self.server.lease_timeout,
                )
                self._deadman(expired)
            next_at += period
            delay = next_at - time.monotonic()
            if delay < 0:
                next_at, delay = time.monotonic(), 0.0
            if self._kick.wait(delay):
                self._kick.clear()

    # -- queries ------------------------------------------------------------------------------------------

    def _on_state(self, query: Any) -> None:
        # Answered on Zenoh's thread: the latest reading is in memory, nothing blocks.
        with query:
            if self._lost is not None:
                query.reply_err(protocol.encode_error(self._lost, "state"))
            elif self._latest is None:
                query.reply_err(
                    protocol.encode_error(GripperError("no state read yet", device=self.name), "state")
                )
            else:
                query.reply(query.key_expr, self._latest)

    def _on_info(self, query: Any) -> None:
        with query:
            if self._lost is not None:
                query.reply_err(protocol.encode_error(self._lost, "info"))
            else:  # with the refusals counted so far (issue 30)
                query.reply(query.key_expr, protocol.dumps({**self._info_base, "refused": self.gate.refused}))

    def _on_command(self, query: Any, command: str) -> None:
        """On Zenoh's thread: parse, and admit or refuse at once (gate.py), before anything is queued."""
        request = None
        try:
            payload = query.payload
            request = protocol.parse_request(command, payload.to_bytes() if payload is not None else b"")
            if str(query.key_expr) != protocol.command_key(self.name, command):
                # A wildcard selector (grippers/**, grippers/*/cmd/stop) reaches every gripper at once: a
                # command is asked of one gripper by its own key, never by a pattern.
                raise ProtocolError(
                    f"a command is asked on its own key {protocol.command_key(self.name, command)}, "
                    f"not on the pattern {query.key_expr}",
                    command=command,
                )
            spec = protocol.COMMANDS[command]
            acquire = command == "control" and request.args["action"] == "acquire"
            needs, take = spec.lease != "free" or acquire, spec.lease == "take" or acquire
            slot = self.gate.admit(request, needs, take, urgent=command in _URGENT)
        except GripperError as exc:
            self._refuse(query, request, command, exc)
            return
        received = self._received(command)
        # Stop, fast stop and acknowledge never queue behind reads or settings (``urgent``: commands.py).
        pool = self.server.urgent if command in _URGENT else self.server.pool
        try:
            pool.submit(self._answer, query, request, slot, received)
        except RuntimeError:  # shutting down
            self.gate.release(slot)
            with query:
                query.reply_err(protocol.encode_error(ConnectionLost("the server is closing"), command))

    def _refuse(self, query: Any, request: protocol.Request | None, command: str, exc: GripperError) -> None:
        if isinstance(exc, AccessDenied):
            self.gate.refused_request(query, request, command, exc)
        self._reply_error(query, exc, command)
        query.drop()

    def _received(self, command: str) -> int:
        """On Zenoh's thread, as a request arrives: the stops received so far, this one counted if a stop."""
        with self._stops_lock:
            if command in _STOPS:
                self._stops += 1
            return self._stops

    def _not_overtaken(self, received: int, command: str) -> None:
        """Refuse what sets the jaws moving when a stop arrived after it (issue 43 §9: 3,000 servo targets
        of the holder waited on the ordinary pool while another client's stop ran at once on the urgent one,
        and the jaws stopped, then went on to the last target). Called under ``_order``."""
        if received < self._stops:
            raise CommandFailed(
                f"{command} not done: a stop arrived after it and before it ran",
                device=self.name,
                command=command,
            )

    def _answer(self, query: Any, request: protocol.Request, slot: Slot, received: int) -> None:
        command = request.command
        try:
            if self._lost is not None:
                raise self._lost
            spec = protocol.COMMANDS[command]
            secret = None
            if spec.lease != "free":
                take = spec.lease == "take"
                if take and self.lease.holder is None and request.lease is None:
                    self.gate.look_for_token(self.server.session, request.client)
                secret = self.gate.check(request, take)
            if spec.motion:
                self._start_motion(query, request, secret, received)
                return  # the motion thread answers and finishes the query
            if command == "control":
                if request.args["action"] == "acquire" and self.lease.holder is None:
                    self.gate.look_for_token(self.server.session, request.client)
                secret = self.gate.control(request, request.args["action"])
                if request.args["action"] == "acquire":
                    with self._order:
                        self._servo_stopped.discard(request.client)  # begins anew
                result = None
            else:
                result = self._execute_taking(request, secret, received)
        except GripperError as exc:
            self._refuse(query, request, command, exc)
            return
        except Exception as exc:
            self._reply_error(query, exc, command)
            query.drop()
            return
        finally:
            self.gate.release(slot)
        try:
            reply = protocol.encode_reply(protocol.DONE, payloads.result_doc(result), secret)
            query.reply(query.key_expr, reply)
        finally:
            query.drop()

    def _execute_taking(self, request: protocol.Request, secret: str | None, received: int) -> Any:
        """Execute; a command that took the lease and failed (a servo target out of limits) gives it back:
        its error reply cannot carry the secret, and nothing was set moving for the deadman to watch."""
        try:
            return self._execute(request, received)
        except BaseException:
            if secret is not None:
                with self._lease_lock:
                    self.lease.release(request.client, secret)
            raise

    def _reply_error(self, query: Any, exc: BaseException, command: str) -> None:
        if not isinstance(exc, GripperError):
            log.exception("%s %s: unexpected error", self.name, command)
        try:
            query.reply_err(protocol.encode_error(exc, command))
        except Exception:  # the client is gone: nothing to tell
            pass

    def _execute(self, request: Any, received: int) -> Any:
        """Call the Gripper method the verb names (grippers/commands.py), with the arguments it took."""
        g, command = self.gripper, request.command
        method = getattr(g, _VERBS[command].name)
        try:
            if command == "servo":
                with self._order:
                    self._not_overtaken(received, command)
                    if request.client in self._servo_stopped:
                        raise CommandFailed(
                            "servoing was ended by another client's stop: stop() ends it here too, then "
                            "servo() begins anew",
                            device=self.name,
                            command=command,
                        )
                    method(**request.args)
                    self._servo_owner = request.client
                return None
            if command in _STOPS:
                with self._order:  # after every start already under way, before any received earlier
                    owner, self._servo_owner = self._servo_owner, None  # both end servoing (Gripper's rule)
                    if owner is not None and owner != request.client and len(self._servo_stopped) < 1024:
                        self._servo_stopped.add(owner)
                    self._servo_stopped.discard(request.client)  # its own stop: it knows servoing ended
                    return method(**request.args)
            return method(**request.args)
        finally:
            if command != "servo":  # a target is answered once queued: the publisher shows its effect
                self._refresh()  # every change is published before the reply

    # -- motions ------------------------------------------------------------------------------------------

    def _start_motion(self, query: Any, request: Any, secret: str | None, received: int) -> None:
        self._servo_owner = None  # a motion command ends servoing (Gripper's rule)
        thread = threading.Thread(
            target=self._run_motion,
            args=(query, request, secret, received),
            name=f"grippers-serve-{self.name}-{request.command}",
        )
        thread.daemon = True
        with self._motions_lock:
            self._motions[thread] = request.client
        thread.start()

    def _run_motion(self, query: Any, request: Any, secret: str | None, received: int) -> None:
        g, a = self.gripper, request.args
        try:
            query.reply(query.key_expr, protocol.encode_reply(protocol.PENDING, None, secret))
            self._kick.set()
            with self._order:  # started, or refused if a stop came after it: never started after the stop
                self._not_overtaken(received, request.command)
                self._servo_stopped.discard(request.client)  # a motion command begins anew
                handle = getattr(g, _VERBS[request.command].name)(**a, wait=False)
            result = handle.wait()
            self._refresh()
            query.reply(query.key_expr, protocol.encode_reply(protocol.DONE, payloads.result_doc(result)))
        except Exception as exc:
            self._refresh()
            self._reply_error(query, exc, request.command)
        finally:
            query.drop()
            with self._motions_lock:
                self._motions.pop(threading.current_thread(), None)

    # -- clients and the lease ------------------------------------------------------------------------------

    def _on_client(self, sample: Any) -> None:
        client = str(sample.key_expr).rsplit("/", 1)[-1]
        zenoh = import_zenoh()
        if sample.kind == zenoh.SampleKind.PUT:
            with self._lease_lock:
                self.lease.client_seen(client)
            return
        with self._lease_lock:
            if client != self.lease.holder:  # a token of no consequence: forgotten here, nothing queued
                self.lease.alive.pop(client, None)
                return
        try:
            self.server.urgent.submit(self._client_gone, client)
        except RuntimeError:
            pass

    def _client_gone(self, client: str) -> None:
        with self._lease_lock:
            held = self.lease.client_gone(client)
        if held:
            log.info("%s: client %s gone; lease freed", self.name, client)
            self._deadman(client)

    def _moves(self, ours: bool) -> bool:
        """Whether the jaws move on someone's behalf: ``ours`` (a motion or servoing we know of), or else
        what the device says (a motion whose wait timed out); unknown counts as moving (the safe side)."""
        if ours:
            return True
        try:
            return self.gripper.state().moving
        except GripperError:
            return True

    def _deadman(self, client: str) -> None:
        """The holder vanished: stop what the device does on its behalf, not only what our threads wait on.

        Only the holder can set the jaws moving, so whatever moves now is its doing: a motion still waited on,
        a servoing, or a motion whose wait timed out (the server's thread has returned, the jaws have not
        stopped). A device at rest is left alone: a stop would loosen a held part on some devices (MSG over
        UART switches the motor off)."""
        with self._motions_lock:
            mine = [t for t, owner in self._motions.items() if owner == client]
        if not self._moves(bool(mine) or self._servo_owner == client):
            return
        self._servo_owner = None
        log.warning("%s: client %s vanished with the jaws under its command; stopping", self.name, client)
        try:
            self.gripper.stop()
        except GripperError as exc:
            log.error("%s: stop after the holder vanished failed: %s", self.name, exc)
        self._kick.set()


class Server:
    """A Zenoh session serving several grippers. ``close()`` withdraws them and closes every gripper."""

    def __init__(
        self,
        grippers: dict[str, Gripper],
        *,
        listen: list[str] | None = None,
        connect: list[str] | None = None,
        config_file: str | None = None,
        scout: bool = False,
        rate: float = 50.0,
        lease_timeout: float = 1.0,
    ) -> None:
        for name in grippers:
            protocol.check_name(name)
        if not rate > 0 or not lease_timeout > 0:
            raise ValueError("rate and lease timeout must be above 0")
        self.grippers = grippers
        self.rate = rate
        self.lease_timeout = lease_timeout
        if listen is None and not config_file:
            listen = [DEFAULT_LISTEN]
        self._listen = listen or []
        self._config = make_config(
            mode="peer",
            listen=listen,
            connect=connect,
            config_file=config_file,
            scout=scout,
            lease_s=lease_timeout,
        )
        n = len(grippers)
        self.pool = ThreadPoolExecutor(max_workers=4 + 2 * n, thread_name_prefix="grippers-serve")
        self.urgent = ThreadPoolExecutor(max_workers=2 + n, thread_name_prefix="grippers-serve-stop")
        self.session: Any = None
        self.served: list[ServedGripper] = []
        self.locators: list[str] = []

    def start(self) -> None:
        self.session = open_session(self._config, "grippers serve")
        try:
            for name, gripper in self.grippers.items():
                served = ServedGripper(self, name, gripper)
                self.served.append(served)
                served.start()
            for served in self.served:
                refuse_duplicate(self.session, served.name, declared=True)
            given = [e for e in self._listen if zenoh_port(e) != 0]
            self.locators = own_locators(self.session) or given
        except BaseException:
            self.close()
            raise

    def url(self, name: str) -> str:
        """The URL that opens a served gripper from another process (the first endpoint we listen on)."""
        if self.locators:
            return f"zenoh://{name}?connect={self.locators[0]}"
        return f"zenoh://{name}"

    def close(self) -> None:
        for served in self.served:
            served.close()
        self.urgent.shutdown(wait=True, cancel_futures=True)
        self.pool.shutdown(wait=True, cancel_futures=True)
        if self.session is not None:
            try:
                self.session.close()
            except Exception:
                pass
            self.session = None
        for gripper in self.grippers.values():
            try:
                gripper.close()
            except Exception as exc:  # every gripper is closed, even after one fails
                log.error("closing %s: %s", gripper, exc)
