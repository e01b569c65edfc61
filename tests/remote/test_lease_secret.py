"""Issue 30, the attacker's side: a raw Zenoh session (eclipse-zenoh only, no grippers code) on the network
knows every id (the client tokens are public) but not the lease secret. It cannot move the jaws another client
holds, cannot keep a dead holder's lease alive, cannot take a free lease without a token of its own, and a
flood of bogus acquisitions leaves the holder's motion and the server's memory alone."""

from __future__ import annotations

import json
import signal
import subprocess
import sys
import threading
import time
import uuid
from pathlib import Path

import pytest
import zenoh

import grippers
from grippers import AccessDenied

from .conftest import ROOT, ServeProcess, sim

pytestmark = pytest.mark.timeout(120)

LEASE = 1.0
MARGIN = 1.0  # the publisher's period, a state read and a stop on a busy machine; the motion is 20 s long
CONTROLLER = str(ROOT / "benchmarks" / "moving_controller.py")


def attacker(endpoint: str) -> zenoh.Session:
    config = zenoh.Config()
    config.insert_json5("mode", '"client"')
    config.insert_json5("connect/endpoints", json.dumps([endpoint]))
    config.insert_json5("scouting/multicast/enabled", "false")
    return zenoh.open(config)


def request(client: str, args: dict[str, object], lease: str | None = None) -> bytes:
    doc: dict[str, object] = {"v": 1, "client": client, "label": "attacker", "args": args}
    if lease is not None:
        doc["lease"] = lease
    return json.dumps(doc).encode()


def ask(session: zenoh.Session, key: str, payload: bytes, timeout: float = 5.0) -> list[dict]:
    """Every reply (errors as their documents), consolidation none: a motion's pending and done both."""
    out = []
    for r in session.get(key, payload=payload, consolidation=zenoh.ConsolidationMode.NONE, timeout=timeout):
        out.append(json.loads((r.ok or r.err).payload.to_bytes()))
    return out


def holders(session: zenoh.Session, name: str) -> list[str]:
    """What anyone learns: the ids of the clients' liveliness tokens."""
    ids = []
    for r in session.liveliness().get(f"grippers/{name}/client/*", timeout=2):
        if r.ok is not None:
            ids.append(str(r.ok.key_expr).rsplit("/", 1)[-1])
    return ids


def info(session: zenoh.Session, name: str) -> dict:
    (reply,) = session.get(f"grippers/{name}/info", timeout=3)
    return json.loads(reply.ok.payload.to_bytes())


def test_the_holders_id_without_the_secret_moves_nothing(serve) -> None:
    """Before: a query naming the holder's id was answered ok and the jaws moved (40 -> 85 mm)."""
    server: ServeProcess = serve(f"g={sim('wsg50')}")
    session = attacker(server.endpoint)
    try:
        with grippers.open(server.urls["g"] + "&label=cell") as g:
            g.home()
            g.move(0.04)
            ids = holders(session, "g")
            assert g.client_id in ids  # the id is public
            refused_before = info(session, "g")["refused"]
            for client in ids:
                for command, args in [
                    ("move", {"width": 0.085}),
                    ("servo", {"width": 0.085}),
                    ("grasp", {"width": 0.085}),
                    ("release", {"width": 0.085}),
                    ("set_soft_limits", {"min_width": 0.0, "max_width": 0.05}),
                    ("control", {"action": "acquire"}),
                    ("control", {"action": "release"}),
                    ("control", {"action": "heartbeat"}),
                ]:
                    for lease in (None, "0" * 32, uuid.uuid4().hex):  # no secret, guesses
                        replies = ask(session, f"grippers/g/cmd/{command}", request(client, args, lease))
                        assert [r.get("error") for r in replies] in (["AccessDenied"], ["ProtocolError"]), (
                            command,
                            lease,
                            replies,
                        )
            time.sleep(0.3)
            state = g.state()
            assert state.width == pytest.approx(0.04, abs=0.001) and not state.moving  # nothing moved
            assert g.move(0.05).width == pytest.approx(0.05, abs=0.001)  # the holder still commands
            assert info(session, "g")["refused"] >= refused_before + 3 * 8 - 1  # counted in the info
    finally:
        session.close()
    server.close()
    assert "refused move from client" in server.stderr_text  # logged: who, what, which session


def test_a_free_lease_needs_a_token_of_ones_own(serve) -> None:
    """Before: a request naming an id with no liveliness token at all took the free lease and moved."""
    server: ServeProcess = serve(f"g={sim('wsg50')}")
    session = attacker(server.endpoint)
    try:
        with grippers.open(server.urls["g"]) as watcher:
            watcher.home()
            watcher.move(0.04)
            watcher.release_control()
            replies = ask(session, "grippers/g/cmd/move", request("nobody", {"width": 0.085}))
            assert [r.get("error") for r in replies] == ["AccessDenied"], replies
            assert "liveliness token" in replies[0]["message"]
            assert watcher.state().width == pytest.approx(0.04, abs=0.001)
            # With a token of its own, the free lease is taken, and its secret is answered to it alone.
            token = session.liveliness().declare_token("grippers/g/client/mine")
            time.sleep(0.2)
            replies = ask(session, "grippers/g/cmd/control", request("mine", {"action": "acquire"}))
            secret = replies[0]["lease"]
            assert len(secret) == 32 and int(secret, 16) >= 0
            with pytest.raises(AccessDenied):
                watcher.move(0.06)
            replies = ask(session, "grippers/g/cmd/move", request("mine", {"width": 0.06}, secret))
            assert [r["status"] for r in replies] == ["pending", "done"], replies
            assert "lease" not in replies[0]  # the secret is answered once, when the lease is taken
            ask(session, "grippers/g/cmd/control", request("mine", {"action": "release"}, secret))
            token.undeclare()
            assert watcher.move(0.05).width == pytest.approx(0.05, abs=0.001)
    finally:
        session.close()


@pytest.mark.parametrize("sig", [signal.SIGKILL, signal.SIGSTOP], ids=["killed", "frozen"])
def test_a_spoofed_token_and_heartbeat_do_not_keep_a_dead_holders_lease(serve, sig: int) -> None:
    """Before: a raw session declaring the dead holder's token and publishing on its heartbeat key kept the
    jaws moving 4 s after the holder was killed. Now only the secret keeps a lease."""
    server: ServeProcess = serve(f"g={sim('wsg50', scale=1)}", "--lease-timeout", str(LEASE))
    url = server.urls["g"]
    proc = subprocess.Popen(
        [sys.executable, CONTROLLER, url, "0.2"], cwd=ROOT, stdout=subprocess.PIPE, text=True
    )
    session = attacker(server.endpoint)
    stop = threading.Event()
    try:
        assert proc.stdout is not None and proc.stdout.readline().strip() == "moving"
        with grippers.open(url) as watcher:
            assert watcher.state().moving
            (holder,) = [i for i in holders(session, "g") if i != watcher.client_id]
            token = session.liveliness().declare_token(f"grippers/g/client/{holder}")
            publisher = session.declare_publisher(f"grippers/g/alive/{holder}")  # the old heartbeat key

            def spoof() -> None:
                beat = request(holder, {"action": "heartbeat"})
                while not stop.wait(0.05):
                    publisher.put(b"")
                    session.get("grippers/g/cmd/control", payload=beat, timeout=1)

            spoofer = threading.Thread(target=spoof, daemon=True)
            spoofer.start()
            time.sleep(0.3)
            proc.send_signal(sig)
            killed = time.monotonic()
            while watcher.state().moving:
                assert time.monotonic() - killed < LEASE + MARGIN, "the spoof kept the dead holder's motion"
                time.sleep(0.01)
            width = watcher.state().width
            assert width > watcher.limits.min_width + 0.03  # stopped far from its target
            time.sleep(0.2)
            assert watcher.state().width == pytest.approx(width, abs=1e-4)
            watcher.move(0.08)  # the lease is free again, for a client with a token of its own
            stop.set()
            spoofer.join(5)
            token.undeclare()
    finally:
        stop.set()
        proc.kill()
        proc.wait(5)
        session.close()


def _rss_kib(pid: int) -> int:
    for line in Path(f"/proc/{pid}/status").read_text().splitlines():
        if line.startswith("VmRSS:"):
            return int(line.split()[1])
    raise AssertionError("no VmRSS")


def test_a_flood_of_bogus_acquisitions_starves_nothing(serve) -> None:
    """Thousands of acquire (and move) requests with fresh ids, with and without tokens, while the holder
    servos and moves: all refused at once (counted), the holder's commands answered as usual, the server's
    memory bounded (what it keeps of clients is capped)."""
    server: ServeProcess = serve(f"g={sim('wsg50')}")
    session = attacker(server.endpoint)
    flood_n = 3000
    tokens = []
    try:
        with grippers.open(server.urls["g"] + "&label=cell") as g:
            g.home()
            g.move(0.04)
            before = info(session, "g")["refused"]
            rss_before = _rss_kib(server.proc.pid)
            done = threading.Event()
            answered: list[int] = []

            def flood() -> None:
                for i in range(flood_n):
                    client = uuid.uuid4().hex
                    if i % 3 == 0 and len(tokens) < 2000:  # tokens too: bounded on the server
                        tokens.append(session.liveliness().declare_token(f"grippers/g/client/{client}"))
                    action = "acquire" if i % 2 else "move"
                    args = {"action": action} if action == "acquire" else {"width": 0.085}
                    key = "grippers/g/cmd/control" if action == "acquire" else "grippers/g/cmd/move"
                    session.get(
                        key,
                        zenoh.handlers.Callback(lambda r: answered.append(1), indirect=False),
                        payload=request(client, args),
                        timeout=10,
                    )
                done.set()

            flooder = threading.Thread(target=flood, daemon=True)
            flooder.start()
            widths = [0.05, 0.03, 0.06, 0.04]
            while not done.is_set():
                for w in widths:
                    assert g.move(w).width == pytest.approx(w, abs=0.001)  # the holder is not starved
                g.servo(0.05)
            flooder.join(30)
            g.stop()
            deadline = time.monotonic() + 30
            while len(answered) < flood_n and time.monotonic() < deadline:
                time.sleep(0.05)
            assert len(answered) == flood_n  # every bogus request was answered (refused), none left queued
            assert info(session, "g")["refused"] - before >= flood_n * 0.99
            assert g.move(0.04).width == pytest.approx(0.04, abs=0.001)
            grown = _rss_kib(server.proc.pid) - rss_before
            assert grown < 64 * 1024, f"the server grew by {grown} KiB"
    finally:
        for t in tokens:
            t.undeclare()
        session.close()


def test_the_secret_never_crosses_a_publication(serve) -> None:
    """Heartbeats are queries (only the server's queryable receives them), not publications any subscriber of
    grippers/** would see."""
    server: ServeProcess = serve(f"g={sim('wsg50')}", "--lease-timeout", "0.4")
    session = attacker(server.endpoint)
    seen: list[bytes] = []
    try:
        sub = session.declare_subscriber(
            "grippers/**",
            zenoh.handlers.Callback(lambda s: seen.append(s.payload.to_bytes()), indirect=False),
        )
        with grippers.open(server.urls["g"]) as g:
            g.home()
            secret = g.device._link.holder.secret
            assert secret
            time.sleep(1.0)  # several heartbeats
            assert g.move(0.05).width == pytest.approx(0.05, abs=0.001)  # still held: heartbeats work
            assert g.device._link.holder.secret == secret
        sub.undeclare()
        assert seen and not any(secret.encode() in p for p in seen)
    finally:
        session.close()


def test_record_over_zenoh_only_observes(serve, tmp_path: Path) -> None:
    """Issue 30 §3: `grippers record zenoh://…` without --do reads the state stream while another client holds
    the lease: it neither needs the lease nor disturbs it (and nothing it sends is refused)."""
    from grippers.cli import main

    server: ServeProcess = serve(f"g={sim('wsg50')}")
    session = attacker(server.endpoint)
    try:
        with grippers.open(server.urls["g"] + "&label=cell") as g:
            g.home()
            out = tmp_path / "run.csv"
            assert main(["record", server.urls["g"], "-o", str(out), "--duration", "0.5"]) == 0
            assert len(out.read_text().splitlines()) > 3
            assert info(session, "g")["refused"] == 0
            assert g.move(0.05).width == pytest.approx(0.05, abs=0.001)  # still the holder
    finally:
        session.close()
