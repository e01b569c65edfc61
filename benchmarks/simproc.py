"""A WSG simulator in a child process, so the client's CPU time and memory are the client's alone.

Child protocol (stdin/stdout, one line each): the child prints the simulator URL, serves until its stdin
closes, then, with ``--record``, writes every packet it sent as JSON ``[[command, payload_hex], ...]``.
"""

from __future__ import annotations

import argparse
import json
import os
import subprocess
import sys
import threading
from pathlib import Path

if __package__ in (None, ""):
    sys.path.insert(0, str(Path(__file__).resolve().parent.parent))

from benchmarks.common import REPO


def _start(cmd: list[str], cpu: int | None) -> subprocess.Popen[str]:
    """The child, on CPU ``cpu`` alone when given (a device has a processor of its own: see device_apart)."""

    def place() -> None:
        if cpu is not None:
            os.sched_setaffinity(0, {cpu})

    return subprocess.Popen(cmd, stdin=subprocess.PIPE, stdout=subprocess.PIPE, text=True, preexec_fn=place)


class WsgSimProcess:
    """``WsgSimProcess(time_scale=…, record=path, cpu=N)``: ``.url``, ``.port``; ``close()`` waits for it."""

    def __init__(self, *, time_scale: float = 1.0, record: str | None = None, cpu: int | None = None) -> None:
        cmd = [sys.executable, str(REPO / "benchmarks" / "simproc.py"), "--time-scale", str(time_scale)]
        if record:
            cmd += ["--record", record]
        self._proc = _start(cmd, cpu)
        assert self._proc.stdout is not None
        line = self._proc.stdout.readline().strip()
        if not line.startswith("wsg+tcp://"):
            self._proc.kill()
            raise RuntimeError(f"simulator child did not start: {line!r}")
        self.url = line
        self.port = int(line.rsplit(":", 1)[1])

    def close(self) -> None:
        assert self._proc.stdin is not None
        self._proc.stdin.close()
        try:
            self._proc.wait(timeout=10)
        except subprocess.TimeoutExpired:
            self._proc.kill()
            self._proc.wait()

    def __enter__(self) -> WsgSimProcess:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()


class MsgSimProcess:
    """Simulated MSG nodes ``0..nodes-1`` on python-can's ``udp_multicast`` bus, served by a child process."""

    GROUP = "239.74.163.2"  # python-can's IPv4 default group (administratively scoped)

    def __init__(self, nodes: int, *, port: int, cpu: int | None = None) -> None:
        listen = f"can://udp_multicast/{self.GROUP}?port={port}"
        cmd = [
            sys.executable,
            str(REPO / "benchmarks" / "simproc.py"),
            "--msg-nodes",
            str(nodes),
            "--listen",
            listen,
        ]
        self._proc = _start(cmd, cpu)
        assert self._proc.stdout is not None
        line = self._proc.stdout.readline().strip()
        if not line.startswith("stepfoc+can://"):
            self._proc.kill()
            raise RuntimeError(f"simulator child did not start: {line!r}")
        self.port = port

    close = WsgSimProcess.close

    def __enter__(self) -> MsgSimProcess:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()


def _msg_child(nodes: int, listen: str) -> None:
    from grippers.drivers.stepfoc.sim import MsgModel, serve_can

    server = serve_can([MsgModel(node=n) for n in range(nodes)], listen)
    print(server.url, flush=True)
    sys.stdin.read()
    server.close()


def _child(time_scale: float, record: str | None) -> None:
    from grippers.drivers.wsg.sim import WsgModel, serve

    server = serve(WsgModel(), "tcp://127.0.0.1:0", time_scale=time_scale)
    sent: list[tuple[int, str]] = []
    if record:
        send = server._send
        lock = threading.Lock()

        def recording_send(link, data: bytes) -> None:  # noqa: ANN001 - the engine's Link
            with lock:
                sent.append((data[3], data[6:-2].hex()))
            send(link, data)

        server._send = recording_send  # type: ignore[method-assign]
    print(server.url, flush=True)
    sys.stdin.read()  # until the parent closes our stdin
    server.close()
    if record:
        Path(record).write_text(json.dumps(sent))


if __name__ == "__main__":
    ap = argparse.ArgumentParser()
    ap.add_argument("--time-scale", type=float, default=1.0)
    ap.add_argument("--record")
    ap.add_argument("--msg-nodes", type=int)
    ap.add_argument("--listen")
    args = ap.parse_args()
    if args.msg_nodes:
        _msg_child(args.msg_nodes, args.listen)
    else:
        _child(args.time_scale, args.record)
