"""The client's side of the control lease (lease.py is the server's): the secret, its heartbeat, giving it
back. One object per ``zenoh://`` gripper, used by client.py.

The secret arrives in the reply to the request that took the lease and goes with every later request; it is
dropped when the server answers AccessDenied to a request that carried it (the lease ended: the holder was
silent too long, its token went, the server restarted), so the next command takes a free lease anew and
says so if it cannot: never a silent re-take. Heartbeats are ``control heartbeat`` *queries*: a query reaches
the server's queryable only, where a publication would show the secret to every subscriber of ``grippers/**``.
"""

from __future__ import annotations

import logging
import threading
from collections.abc import Callable
from typing import Any

from ..errors import AccessDenied, GripperError
from . import protocol
from .session import import_zenoh

log = logging.getLogger("grippers.remote")

# query(key, payload, command, timeout) -> result: the client's own query (bounded, errors raised as classes)
Query = Callable[[str, bytes, str, float], Any]


class LeaseHolder:
    def __init__(self, served_name: str, client_id: str, label: str, device: str) -> None:
        self.served_name, self.client_id, self.label, self.device = served_name, client_id, label, device
        self.secret: str | None = None
        self._control_key = protocol.command_key(served_name, "control")

    def request(self, args: dict[str, Any]) -> bytes:
        """A request document: with the secret while this client holds the lease."""
        return protocol.encode_request(self.client_id, self.label, args, self.secret)

    def granted(self, secret: str | None) -> None:
        if secret is not None:
            self.secret = secret  # only we received it: a reply goes to the querier alone

    def refused(self, error: GripperError, sent: str | None) -> None:
        """An error reply to a request that carried ``sent``: AccessDenied means that lease has ended."""
        if isinstance(error, AccessDenied) and sent is not None and self.secret == sent:
            self.secret = None

    def beat(self, session: Any, period: float) -> None:
        """One heartbeat, not waited for (a frozen server must not stall the beating thread)."""
        secret = self.secret
        if secret is None:
            return
        zenoh = import_zenoh()

        def on_reply(reply: Any) -> None:
            if reply.err is not None and not protocol.is_query_timeout(reply.err.payload.to_bytes()):
                self.refused(
                    protocol.decode_error(reply.err.payload.to_bytes(), "control", self.device), secret
                )

        payload = protocol.encode_request(self.client_id, self.label, {"action": "heartbeat"}, secret)
        session.get(
            self._control_key,
            zenoh.handlers.Callback(on_reply, indirect=False),
            payload=payload,
            timeout=period,
        )

    def give_back(self, query: Query, timeout: float) -> None:
        """Release the lease if held (close(), the end of an outage); a lease that ended already is fine."""
        secret, self.secret = self.secret, None
        if secret is None:
            return
        payload = protocol.encode_request(self.client_id, self.label, {"action": "release"}, secret)
        try:
            query(self._control_key, payload, "control", timeout)
        except GripperError:
            pass


class LossListeners:
    """The ``link`` feature's listeners of a ``zenoh://`` device (grippers/device.py ``Link``): told once,
    from a thread of ours (the loss is noticed on Zenoh's thread, or the servo loop's), in the order they
    came: the gripper's own first (it ends servoing), then the user's ``on_connection`` callbacks."""

    def __init__(self) -> None:
        self._listeners: list[Callable[[bool], Any]] = []

    def add(self, callback: Callable[[bool], Any]) -> Callable[[], None]:
        self._listeners.append(callback)

        def remove() -> None:
            if callback in self._listeners:
                self._listeners.remove(callback)

        return remove

    def tell(self) -> None:
        """Tell every listener the link is gone; returns at once."""

        def run() -> None:
            for fn in list(self._listeners):
                try:
                    fn(False)
                except Exception:  # a bug in a user's callback must not hide the loss from the others
                    log.exception("on_connection callback raised")

        threading.Thread(target=run, name="grippers-remote-lost", daemon=True).start()
