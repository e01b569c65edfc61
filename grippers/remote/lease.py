"""The control lease of one served gripper: who may command motion. Pure bookkeeping, time passed in.

Any number of clients observe; one at a time commands. A client holds the lease by its liveliness token
(``grippers/<name>/client/<id>``): when the token goes away (process killed, session closed, network cut
detected by Zenoh's transport lease) the server stops what the holder started and frees the lease. A holder
whose token the server has never seen (it vanished before its declaration arrived) loses the lease after
the timeout, so a lease can never outlive its holder by more than that.
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

    def acquire(self, client: str, label: str, now: float, device: str) -> None:
        self.check(client, label, "control", True, now, device)

    def release(self, client: str) -> bool:
        if self.holder == client:
            self.holder, self.label = None, ""
            return True
        return False

    def client_seen(self, client: str) -> None:
        self.alive.add(client)

    def client_gone(self, client: str) -> bool:
        """Forget a client; True when it held the lease (now freed): its motion must be stopped."""
        self.alive.discard(client)
        return self.release(client)

    def expired(self, now: float) -> str | None:
        """The holder, freed, when its token was never seen within the timeout of taking the lease."""
        if self.holder is not None and self.holder not in self.alive and now - self.since > self.timeout:
            holder = self.holder
            self.release(holder)
            return holder
        return None
