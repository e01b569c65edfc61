"""Who gets in: the lease checks of one served gripper, its refusals (logged, counted), and a bound on the
work queued for clients that do not hold the lease.

Zenoh calls the server's queryables on its own network threads; a request is admitted (or refused) there,
before any of it is queued, so a session flooding commands with fresh ids costs a parse and a comparison
each and grows nothing: the lease holder's requests are never queued behind the flood, and what others may
have queued at once is bounded (``MAX_QUEUED``). The lease itself is lease.py; the server asks here.
"""

from __future__ import annotations

import logging
import threading
import time
from typing import Any

from ..errors import AccessDenied, GripperError, ServerBusy
from . import protocol
from .lease import Lease
from .protocol import Request

log = logging.getLogger("grippers.remote")

MAX_QUEUED = 64  # requests of non-holders queued at once per gripper; more are refused at once ("busy")
# Of those, requests from clients whose liveliness token the server has not seen (a raw query, a flood with
# fresh ids): each may wait TOKEN_LOOKUP_S on a pool thread for a token that never comes, and can then only
# be refused. They get a lane of their own this narrow, so they never fill the queue nor the pool a client
# the server can watch needs (issue 43 §4: a flood of tokenless acquisitions failed a legitimate control()
# 17-19 times in 20).
MAX_UNSEEN = 2
LOG_BURST = 10  # refusals logged one by one per LOG_WINDOW_S; the rest are summed up in one line
LOG_WINDOW_S = 10.0
TOKEN_LOOKUP_S = 0.5  # how long a free lease's taker's token is looked for when not seen yet


class Slot:
    """Where an admitted request was counted (:meth:`Gate.admit`); :meth:`Gate.release` gives it back."""

    def __init__(self, name: str) -> None:
        self.name = name

    def __repr__(self) -> str:
        return f"<slot {self.name}>"


HOLDER, SEEN, UNSEEN = Slot("holder"), Slot("seen"), Slot("unseen")


class Gate:
    def __init__(self, name: str, lease_timeout: float) -> None:
        self.name = name
        self.lease = Lease(lease_timeout)
        self.lock = threading.Lock()
        self.refused = 0  # requests refused for want of the lease secret (served in the info)
        self._queued = 0
        self._unseen = 0  # of _queued, the requests of clients whose token was not seen
        self._window_at = -LOG_WINDOW_S
        self._window_logged = 0
        self._window_quiet = 0

    # -- admission, on Zenoh's thread ---------------------------------------------------------------------

    def admit(self, request: Request, needs_lease: bool, take: bool, urgent: bool = False) -> Slot:
        """Refuse at once what the lease refuses anyway; :data:`HOLDER` when the request is the holder's
        (never bounded), else the lane it was queued in within its bound (``release()`` it when answered).
        ``urgent`` (stop, fast stop): never put in the narrow lane of the unseen."""
        with self.lock:
            if self.lease.proves(request.client, request.lease):
                return HOLDER
            if needs_lease and (request.lease is not None or self.lease.holder is not None):
                # Not the holder's: the authoritative check (run again when executed) says why.
                self.lease.check(
                    request.client, request.label, request.lease, request.command, take, 0.0, self.name
                )
            if self._queued >= MAX_QUEUED:
                raise ServerBusy(
                    f"{MAX_QUEUED} requests of other clients are queued; try again", device=self.name
                )
            if urgent or request.client in self.lease.alive:
                self._queued += 1
                return SEEN
            if self._unseen >= MAX_UNSEEN:
                raise ServerBusy(
                    f"{MAX_UNSEEN} requests of clients without a liveliness token are queued; try again "
                    "(a zenoh:// client declares one)",
                    device=self.name,
                )
            self._queued += 1
            self._unseen += 1
            return UNSEEN

    def release(self, slot: Slot) -> None:
        with self.lock:
            if slot is not HOLDER:
                self._queued -= 1
            if slot is UNSEEN:
                self._unseen -= 1

    # -- the lease, when a request is executed --------------------------------------------------------------

    def check(self, request: Request, take: bool) -> str | None:
        """The lease check proper (AccessDenied); the new secret when this request took the lease."""
        with self.lock:
            before = self.lease.holder
            secret = self.lease.check(
                request.client,
                request.label,
                request.lease,
                request.command,
                take,
                time.monotonic(),
                self.name,
            )
            if self.lease.holder != before:
                log.info("%s: control lease taken by %s", self.name, self.lease.describe())
        return secret

    def look_for_token(self, session: Any, client: str) -> None:
        """A free lease goes to a client whose liveliness token the server can watch (the deadman's fast
        path). Its token usually arrived before its first request; if not seen yet, asked once (bounded)."""
        with self.lock:
            if client in self.lease.alive:
                return
        try:
            replies = session.liveliness().get(protocol.client_key(self.name, client), timeout=TOKEN_LOOKUP_S)
            found = any(r.ok is not None for r in replies)
        except Exception:  # the session is closing: not found
            found = False
        if found:
            with self.lock:
                self.lease.client_seen(client)

    def control(self, request: Request, action: str) -> str | None:
        """``control``: acquire (the secret, when taken now), heartbeat and release (with the secret)."""
        if action == "acquire":
            return self.check(request, True)
        with self.lock:
            if action == "heartbeat":
                if not self.lease.proves(request.client, request.lease):
                    raise AccessDenied(
                        "a heartbeat keeps a lease only with its secret (the lease has ended, or it is "
                        "another client's)",
                        device=self.name,
                        command="control",
                        holder=self.lease.label or self.lease.holder,
                    )
                self.lease.heard_at = time.monotonic()
                return None
            if self.lease.release(request.client, request.lease):
                log.info("%s: control lease released by client %s", self.name, request.client)
            elif request.lease is not None or self.lease.holder == request.client:
                raise AccessDenied("only the lease's secret releases it", device=self.name, command="control")
        return None

    # -- refusals ------------------------------------------------------------------------------------------

    def refused_request(self, query: Any, request: Request | None, command: str, exc: GripperError) -> None:
        """Count and log a refusal: who the request says it is, and which Zenoh session sent it where Zenoh
        tells (a query's source info, set by queriers that choose to). Logged one by one up to LOG_BURST
        per LOG_WINDOW_S, then summed up: a flood must not flood the log too."""
        now = time.monotonic()
        with self.lock:
            self.refused += 1
            if now - self._window_at > LOG_WINDOW_S:
                if self._window_quiet:
                    log.warning(
                        "%s: %d more refused request(s) not logged one by one", self.name, self._window_quiet
                    )
                self._window_at, self._window_logged, self._window_quiet = now, 0, 0
            if self._window_logged >= LOG_BURST:
                self._window_quiet += 1
                return
            self._window_logged += 1
        source = getattr(query, "source_info", None)
        sid = getattr(source, "source_id", None) if source is not None else None
        who = f"client {request.client!r} (label {request.label!r})" if request is not None else "a request"
        log.warning(
            "%s: refused %s from %s, Zenoh session %s: %s",
            self.name,
            command,
            who,
            getattr(sid, "zid", None) or "not told",
            exc.message,
        )
