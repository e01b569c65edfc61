"""The control lease of one served gripper: who may command motion. Pure bookkeeping, time passed in.

Any number of clients observe; one at a time commands. The lease is a secret, not a name (issue 30): taking
it (``control acquire``, or the first motion command on a free lease) answers the taker, and only it, with
128 random bits new for every acquisition; every command that needs the lease and every heartbeat
(``control heartbeat``) carries them in the request's ``lease`` field. A client id is public (everyone sees
the liveliness tokens ``grippers/<name>/client/<id>``), so an id alone is worth nothing: a request without
the holder's secret is refused and changes nothing, and only a request with it shows the holder alive.

The holder's liveliness token only ever *ends* a lease (its deletion: process killed, session closed, link
lost: the fast path of the deadman); it never keeps one. Zenoh notices a silent link only after the link
lease *the client* announced, so the server keeps its own bound: a holder must be heard from (a request or a
heartbeat with its secret) at least every ``timeout``; one that is not loses the lease, and what it set
moving is stopped. A free lease is taken only by a client whose token the server has seen, so that the fast
path can end what it starts.

What the server remembers of clients is bounded (``MAX_TRACKED``): a session declaring tokens by the
thousand, or flooding ``acquire`` with fresh ids, grows nothing but counters.
"""

from __future__ import annotations

import hmac
import secrets
from collections import OrderedDict
from dataclasses import dataclass

from ..errors import AccessDenied

SECRET_BYTES = 16  # 128 bits
MAX_TRACKED = 1024  # client tokens remembered; the oldest is forgotten first (it can only cost a lookup)


@dataclass
class Lease:
    timeout: float
    holder: str | None = None
    label: str = ""
    since: float = 0.0

    def __post_init__(self) -> None:
        self.alive: OrderedDict[str, None] = OrderedDict()
        self.heard_at = 0.0  # when the holder last showed life (a request or a heartbeat with its secret)
        self._secret: str | None = None

    def describe(self) -> str:
        return f"{self.label or 'a client'} (client {self.holder})"

    def proves(self, client: str, secret: str | None) -> bool:
        """Whether a request is the holder's: its id and the secret of the current acquisition."""
        if self.holder is None or self._secret is None or secret is None or client != self.holder:
            return False
        return hmac.compare_digest(secret.encode(), self._secret.encode())

    def check(
        self, client: str, label: str, secret: str | None, command: str, take: bool, now: float, device: str
    ) -> str | None:
        """Raise AccessDenied unless the request is the holder's (or takes a free lease, when ``take``);
        the new secret when this request took the lease, else None."""
        if self.proves(client, secret):
            self.heard_at = now
            return None
        if secret is not None:
            # A secret that is not the current one: a lease that ended (freed when its holder went silent,
            # stopped by the deadman, a restarted server) or a guess. Never a silent re-take: the client
            # learns its lease is gone and takes a new one only by a request that asks to (no secret).
            raise AccessDenied(
                "this lease has ended (or the secret is wrong); a command without one takes a free lease",
                device=device,
                command=command,
                holder=self.label or self.holder,
            )
        if self.holder is not None:
            raise AccessDenied(
                f"the control lease is held by {self.describe()}; stop() and fast_stop() are always accepted",
                device=device,
                command=command,
                holder=self.label or self.holder,
            )
        if not take:
            return None  # a free lease: a command that only needs nobody else to hold it
        if client not in self.alive:
            raise AccessDenied(
                f"no liveliness token grippers/<name>/client/{client} is declared: a lease is taken by a "
                "client the server can watch",
                device=device,
                command=command,
            )
        self.holder, self.label, self.since, self.heard_at = client, label, now, now
        self._secret = secrets.token_hex(SECRET_BYTES)
        return self._secret

    def release(self, client: str, secret: str | None = None, *, proven: bool = False) -> bool:
        """Free the lease; a client releases with its secret, the server itself (``proven``) by id."""
        if self.holder == client and (proven or self.proves(client, secret)):
            self.holder, self.label, self._secret = None, "", None
            return True
        return False

    def client_seen(self, client: str) -> None:
        self.alive[client] = None
        self.alive.move_to_end(client)
        while len(self.alive) > MAX_TRACKED:
            self.alive.popitem(last=False)

    def client_gone(self, client: str) -> bool:
        """Forget a client; True when it held the lease (now freed): its motion must be stopped."""
        self.alive.pop(client, None)
        return self.release(client, proven=True)

    def expired(self, now: float) -> str | None:
        """The holder, freed, when it has not been heard from within the timeout."""
        if self.holder is not None and now - max(self.heard_at, self.since) > self.timeout:
            holder = self.holder
            self.release(holder, proven=True)
            return holder
        return None
