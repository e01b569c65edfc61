"""Issue 43 §4: requests that can only be refused do not crowd out a client the server can watch, and
``ServerBusy`` arrives as its own type.

Two sessions flood tokenless acquisitions while the lease is free (fresh client ids, no liveliness token:
each waited 0.5 s on a pool thread for a token that never came, then was refused). Before, a legitimate
client's ``control()`` failed 17-19 times in 20 with ``ServerBusy``, which arrived as a plain GripperError.
"""

from __future__ import annotations

import json
import threading
import uuid

import pytest

import grippers
from grippers import ServerBusy
from grippers.remote import protocol

from .conftest import ServeProcess, sim
from .test_faults import _raw_session

pytestmark = pytest.mark.timeout(120)


def _acquire(client: str) -> bytes:
    return json.dumps({"v": 1, "client": client, "label": "flood", "args": {"action": "acquire"}}).encode()


def test_a_flood_of_tokenless_acquisitions_does_not_crowd_out_a_watched_client(serve) -> None:
    server: ServeProcess = serve(f"g={sim('wsg50')}")
    sessions = [_raw_session(server.endpoint) for _ in range(2)]
    stop = threading.Event()
    busy: list[str] = []

    def flood(session: object) -> None:
        while not stop.is_set():
            handlers = [
                session.get("grippers/g/cmd/control", payload=_acquire(uuid.uuid4().hex), timeout=5)  # type: ignore[attr-defined]
                for _ in range(200)
            ]
            for handler in handlers:  # wait for this burst's answers: the flood stays at ~100 in flight
                for reply in handler:
                    if reply.err is not None:
                        doc = json.loads(reply.err.payload.to_bytes())
                        busy.append(doc["error"])

    threads = [threading.Thread(target=flood, args=(s,), daemon=True) for s in sessions]
    g = grippers.open(server.urls["g"])
    failures: list[BaseException] = []
    try:
        g.state()
        for t in threads:
            t.start()
        while len(busy) < 100:  # the flood is under way
            threading.Event().wait(0.05)
        for _ in range(20):
            try:
                with g.control():
                    pass
            except grippers.GripperError as exc:
                failures.append(exc)
    finally:
        stop.set()
        for t in threads:
            t.join(30)
        g.close()
        for s in sessions:
            s.close()
    assert failures == [], failures
    assert "ServerBusy" in busy  # the flood itself is told it is refused, by the error's own name


def test_server_busy_crosses_the_wire_as_its_own_type() -> None:
    data = protocol.encode_error(ServerBusy("64 requests of other clients are queued", device="g"), "move")
    error = protocol.decode_error(data, "move", "g@zenoh://g")
    assert type(error) is ServerBusy and "queued" in error.message
