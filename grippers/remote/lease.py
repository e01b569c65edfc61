"""The control lease of one served gripper: who may command motion. Pure bookkeeping, time passed in.

Any number of clients observe; one at a time commands. A client holds the lease by its liveliness token
(``grippers/<name>/client/<id>``): when the token goes away (process killed, session closed, network cut
detected by Zenoh's transport lease) the server stops what the holder started and frees the lease.

Zenoh notices a silent link only after the link lease *the client* announced, which a client written with
another binding may leave at Zenoh's 10 s. So the server keeps its own bound: a holder must be heard from
(a request, or a heartbeat on ``grippers/<name>/alive/<id>``) at least every ``timeout``; one that is not
loses the lease, and what it set moving is stopped. A holder whose token the server never saw falls under
the same rule, so a lease can never outlive its holder's silence by more than ``timeout``.
"""

from __future__ import annotations

from dataclasses import dataclass

from ..errors import AccessDenied


@dataclass
class Lease:
    timeout: float
    holder: str | None = None
    label: str = ""
    since: float = 0.0

    def __post_init__(self) -> None:
        self.alive: set[str] = set()
        self.heard_at = 0.0  # when the holder last showed life (request or heartbeat)

    def describe(self) -> str:
        return f"{self.label or 'a client'} (client {self.holder})"

    def check(self, client: str, label: str, command: str, take: bool, now: float, device: str) -> None:
        """Raise AccessDenied if another client holds the lease; take a free one when ``take``."""
        if self.holder is not None and self.holder != client:
            raise AccessDenied(
                f"the control lease is held by {self.describe()}; stop() and fast_stop() are always accepted",
                device=device,
                command=command,
                holder=self.label or self.holder,
            )
        if take and self.holder is None:
            self.holder, self.label, self.since = client, label, now
        if self.holder == client:
            self.heard_at = now

    def acquire(self, client: str, label: str, now: float, device: str) -> None:
        self.check(client, label, "control", True, now, device)

    def release(self, client: str) -> bool:
        if self.holder == client:
            self.holder, self.label = None, ""
            return True
        return False

    def heard(self, client: str, now: float) -> None:
        """A request or a heartbeat from ``client``: the holder is alive now."""
        if client == self.holder:
            self.heard_at = now

    def client_seen(self, client: str) -> None:
        self.alive.add(client)

    def client_gone(self, client: str) -> bool:
        """Forget a client; True when it held the lease (now freed): its motion must be stopped."""
        self.alive.discard(client)
        return self.release(client)

    def expired(self, now: float) -> str | None:
        """The holder, freed, when it has not been heard from within the timeout."""
        if self.holder is not None and now - max(self.heard_at, self.since) > self.timeout:
            holder = self.holder
            self.release(holder)
            return holder
        return None
