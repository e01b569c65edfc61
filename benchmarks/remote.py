"""Targets 8-10: grippers served over Zenoh (docs/remote.md), each against a baseline of the same run.

8. ``state()`` of a ``zenoh://`` gripper vs a bare Zenoh get and reply of the same payload size, both servers
   in a child process on loopback, calls alternated in slices so machine noise hits both sides alike.
9. Eight grippers publishing state at 100 Hz to two subscribers: every publication seen, in order, by both;
   the server's CPU per gripper (from /proc, user + system).
10. Lease failover: a controlling process killed mid-motion; the time until the published state says the
   motion stopped, against the lease timeout.
"""

from __future__ import annotations

import os
import re
import select
import signal
import subprocess
import sys
import textwrap
import threading
import time
from pathlib import Path

if __package__ in (None, ""):
    sys.path.insert(0, str(Path(__file__).resolve().parent.parent))

from benchmarks.common import REPO, Result, median, us

BARE_SERVER = textwrap.dedent(
    """
    import sys, time, zenoh
    size = int(sys.argv[1])
    config = zenoh.Config()
    config.insert_json5("mode", '"peer"')
    config.insert_json5("listen/endpoints", '["tcp/127.0.0.1:0"]')
    config.insert_json5("scouting/multicast/enabled", "false")
    config.insert_json5("adminspace/enabled", "true")
    session = zenoh.open(config)
    payload = b"x" * size
    queryable = session.declare_queryable("bench/echo", lambda q: q.reply(q.key_expr, payload))
    import json
    zid = str(session.zid())
    for r in session.get(f"@/{zid}/*", timeout=2):
        if r.ok is not None:
            try:
                print("serving at", json.loads(r.ok.payload.to_bytes())["locators"][0], flush=True)
            except (KeyError, ValueError, IndexError):
                pass
    sys.stdin.read()
    """
)


class Child:
    """A child process that prints lines ``... serving at URL``; ``urls`` in order of printing."""

    def __init__(self, cmd: list[str], expected: int, timeout: float = 30.0) -> None:
        self.proc = subprocess.Popen(
            cmd, cwd=REPO, stdin=subprocess.PIPE, stdout=subprocess.PIPE, stderr=subprocess.DEVNULL
        )
        assert self.proc.stdout is not None
        fd, seen, deadline = self.proc.stdout.fileno(), "", time.monotonic() + timeout
        self.urls: list[str] = []
        while len(self.urls) < expected and time.monotonic() < deadline:
            if select.select([fd], [], [], 0.2)[0]:
                chunk = os.read(fd, 65536).decode()
                if not chunk:
                    break
                seen += chunk
                self.urls = re.findall(r"serving at (\S+)", seen)
        if len(self.urls) < expected:
            self.close()
            raise RuntimeError(f"{cmd[2:5]} did not start: {seen!r}")

    def cpu_seconds(self) -> float:
        with open(f"/proc/{self.proc.pid}/stat") as f:
            fields = f.read().rsplit(")", 1)[1].split()
        return (int(fields[11]) + int(fields[12])) / os.sysconf("SC_CLK_TCK")  # utime + stime

    def close(self) -> None:
        if self.proc.poll() is None:
            self.proc.send_signal(signal.SIGTERM)
            try:
                self.proc.wait(15)
            except subprocess.TimeoutExpired:
                self.proc.kill()
                self.proc.wait(5)


def serve(*args: str) -> Child:
    targets = [a for a in args if "=" in a and not a.startswith("-")]
    cmd = [sys.executable, "-m", "grippers", "serve", *args, "--listen", "tcp/127.0.0.1:0"]
    return Child(cmd, len(targets))


def state_round_trip(quick: bool) -> Result:
    import zenoh

    import grippers
    from grippers.remote import protocol

    slices, per_slice = (6, 100) if quick else (20, 250)
    server = serve("g=sim://wsg50?time_scale=50")
    try:
        g = grippers.open(server.urls[0])
        size = len(protocol.dumps(protocol_state(g)))
        bare = Child([sys.executable, "-c", BARE_SERVER, str(size)], 1)
        try:
            config = zenoh.Config()
            config.insert_json5("mode", '"client"')
            config.insert_json5("connect/endpoints", f'["{bare.urls[0]}"]')
            config.insert_json5("scouting/multicast/enabled", "false")
            session = zenoh.open(config)
            try:
                ours: list[float] = []
                base: list[float] = []
                for _ in range(slices):
                    t0 = time.perf_counter()
                    for _ in range(per_slice):
                        g.state()
                    ours.append((time.perf_counter() - t0) / per_slice)
                    t0 = time.perf_counter()
                    for _ in range(per_slice):
                        (reply,) = session.get("bench/echo", timeout=2)
                        reply.ok.payload.to_bytes()
                    base.append((time.perf_counter() - t0) / per_slice)
            finally:
                session.close()
        finally:
            bare.close()
        g.close()
    finally:
        server.close()
    mine, theirs = median(ours), median(base)
    ratio = mine / theirs
    return Result(
        "8 remote state() round trip",
        us(mine),
        f"{us(theirs)} bare get",
        f"{ratio:.2f}x",
        "<= 1.5x",
        ratio <= 1.5,
        [f"{size}-byte payload; medians of {slices} alternating slices of {per_slice} calls"],
    )


def protocol_state(g: object) -> dict:
    from grippers.remote import payloads

    return payloads.state_doc(g.state(), 1)  # type: ignore[attr-defined]


def publish_load(quick: bool) -> Result:
    import json

    import zenoh

    seconds = 5.0 if quick else 60.0
    names = [f"g{i}" for i in range(8)]
    targets = [f"{n}=sim://{'wsg50' if i % 2 else 'msg-150'}?time_scale=50" for i, n in enumerate(names)]
    server = serve(*targets, "--rate", "100")
    endpoint = server.urls[0].split("connect=", 1)[1]
    seen: list[dict[str, list[int]]] = [{n: [] for n in names}, {n: [] for n in names}]
    locks = [threading.Lock(), threading.Lock()]
    sessions, subs = [], []
    try:
        for k in range(2):
            config = zenoh.Config()
            config.insert_json5("mode", '"client"')
            config.insert_json5("connect/endpoints", f'["{endpoint}"]')
            config.insert_json5("scouting/multicast/enabled", "false")
            s = zenoh.open(config)
            sessions.append(s)

            def on_sample(sample: object, k: int = k) -> None:
                name = str(sample.key_expr).split("/")[1]  # type: ignore[attr-defined]
                seq = json.loads(sample.payload.to_bytes())["seq"]  # type: ignore[attr-defined]
                with locks[k]:
                    seen[k][name].append(seq)

            subs.append(s.declare_subscriber("grippers/*/state", on_sample))
        time.sleep(0.5)
        cpu0, t0 = server.cpu_seconds(), time.monotonic()
        time.sleep(seconds)
        cpu1, t1 = server.cpu_seconds(), time.monotonic()
        for sub in subs:
            sub.undeclare()
    finally:
        for s in sessions:
            s.close()
        server.close()
    lost = disorder = 0
    rates = []
    for per in seen:
        for seqs in per.values():
            if not seqs:
                lost += 1
                continue
            disorder += sum(1 for a, b in zip(seqs, seqs[1:], strict=False) if b <= a)
            lost += (seqs[-1] - seqs[0] + 1) - len(set(seqs))
            rates.append(len(seqs) / (t1 - t0 + 0.5))
    cpu_per_gripper = (cpu1 - cpu0) / (t1 - t0) / len(names)
    ok = lost == 0 and disorder == 0
    return Result(
        "9 8 grippers x 100 Hz, 2 subscribers",
        f"{lost} lost, {disorder} out of order",
        f"{min(rates):.0f}-{max(rates):.0f} states/s each",
        f"{cpu_per_gripper * 100:.1f} % CPU/gripper",
        "none lost",
        ok,
        [f"{seconds:g} s; server CPU (user+system) {cpu_per_gripper * 100:.1f} % of a core per gripper"],
    )


CONTROLLER = str(Path(__file__).resolve().parent / "moving_controller.py")


def lease_failover(quick: bool) -> Result:
    """SIGKILL (the process dies: its connection closes at once) and SIGSTOP (a frozen process or a cut
    cable: the connection stays open and silent, so only the link lease can tell)."""
    import grippers

    lease = 1.0
    tries = 2 if quick else 5
    kinds = [signal.SIGKILL, signal.SIGSTOP] * tries
    server = serve("g=sim://wsg50?time_scale=1", "--lease-timeout", str(lease), "--rate", "200")
    times = []
    try:
        url = server.urls[0]
        with grippers.open(url) as watcher:
            for sig in kinds:
                cmd = [sys.executable, CONTROLLER, url, "0.3"]
                proc = subprocess.Popen(cmd, cwd=REPO, stdout=subprocess.PIPE)
                assert proc.stdout is not None and proc.stdout.readline().strip() == b"moving"
                with watcher.stream(rate_hz=1000) as states:
                    proc.send_signal(sig)
                    killed = time.monotonic()
                    while True:
                        st = states.get(5)
                        if not st.moving:
                            break
                    times.append(time.monotonic() - killed)
                proc.kill()
                proc.wait(5)
                if proc.stdout:
                    proc.stdout.close()
    finally:
        server.close()
    worst = max(times)
    kills = ", ".join(f"{t * 1000:.0f}" for t in times[0::2])
    stops = ", ".join(f"{t * 1000:.0f}" for t in times[1::2])
    return Result(
        "10 lease failover",
        f"{worst * 1000:.0f} ms worst",
        f"{lease * 1000:.0f} ms lease",
        f"{worst / lease:.2f}x lease",
        "<= lease + 100 ms",
        worst <= lease + 0.1,
        [f"SIGKILL: {kills} ms; SIGSTOP (silent link): {stops} ms"],
    )


def run(quick: bool) -> list[Result]:
    return [state_round_trip(quick), publish_load(quick), lease_failover(quick)]
