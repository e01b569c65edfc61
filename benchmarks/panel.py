"""Issue 42 §5: the panel's cost and its Stop button's delay.

Target 16, state to the browser: four WSG simulators (child processes), ``grippers panel`` over them (a child
process), and a WebSocket client counting the states each gripper's card receives per second, while the
panel process's CPU time is read from /proc. Goal: 20 Hz or more per gripper with the panel at most 10 % of
one core. Baseline, same run: a bare process streaming the same four grippers at the panel's rate with no web
server (``Gripper.stream``), so the ratio is what the web side adds.

Target 17, Stop: chromium (Debian's, driven by Playwright) clicks the card's Stop button; the figure is the
time from the click to the stop command (0x22) arriving at the simulator, read from the simulator's own log
(its receive hook, in a child process, on the same monotonic clock). Goal: p99 at most 50 ms on loopback.
Baseline, same run: the same click in a bare page whose button sends one WebSocket message to a bare
Starlette server (the browser, the click and the socket, with no panel).
"""

from __future__ import annotations

import argparse
import json
import os
import statistics
import subprocess
import sys
import threading
import time
from pathlib import Path
from typing import Any

if __package__ in (None, ""):
    sys.path.insert(0, str(Path(__file__).resolve().parent.parent))

from benchmarks.common import REPO, Result
from benchmarks.simproc import WsgSimProcess

STOP = b"\xaa\xaa\xaa\x22"  # a WSG packet's preamble and the STOP command id (docs/protocols.md)
CHROMIUM = os.environ.get("GRIPPERS_CHROMIUM", "/usr/bin/chromium")

_BARE_STREAMS = """
import sys, grippers
gs = [grippers.open(u) for u in sys.argv[1:]]
streams = [g.stream(25.0, callback=lambda st: None) for g in gs]
print("ready", flush=True)
sys.stdin.read()
for s in streams: s.close()
for g in gs: g.close()
"""

_BARE_PAGE = """<!doctype html><html><head><meta charset="utf-8"><title>bare</title></head><body>
<button id="b">Stop</button><script>
const ws = new WebSocket(`ws://${location.host}/ws`);
ws.onopen = () => { document.title = "open"; };
document.getElementById("b").addEventListener("click", () => ws.send("stop"));
</script></body></html>"""


def _cpu_seconds(pid: int) -> float:
    fields = Path(f"/proc/{pid}/stat").read_text().rsplit(")", 1)[1].split()
    return (int(fields[11]) + int(fields[12])) / os.sysconf("SC_CLK_TCK")  # utime + stime


def _cpu_share(pid: int, seconds: float) -> float:
    """The share of one core ``pid`` used over ``seconds`` from now."""
    c0, t0 = _cpu_seconds(pid), time.monotonic()
    time.sleep(seconds)
    return (_cpu_seconds(pid) - c0) / (time.monotonic() - t0)


def _panel(targets: list[str]) -> tuple[subprocess.Popen[str], str]:
    proc = subprocess.Popen(
        [sys.executable, "-m", "grippers", "panel", *targets, "--json"],
        stdout=subprocess.PIPE,
        stderr=subprocess.DEVNULL,
        text=True,
        cwd=REPO,
    )
    assert proc.stdout is not None
    line = proc.stdout.readline()
    if not line:
        proc.kill()
        raise RuntimeError("grippers panel did not start (is the panel extra installed?)")
    return proc, str(json.loads(line)["url"])


def _stop(proc: subprocess.Popen[str]) -> None:
    proc.terminate()
    try:
        proc.wait(15)
    except subprocess.TimeoutExpired:
        proc.kill()
        proc.wait()


def state_load(quick: bool) -> Result:
    from websockets.sync.client import connect

    seconds = 4.0 if quick else 12.0
    sims = [WsgSimProcess() for _ in range(4)]
    try:
        urls = [s.url for s in sims]
        bare = subprocess.Popen(
            [sys.executable, "-c", _BARE_STREAMS, *urls],
            stdin=subprocess.PIPE,
            stdout=subprocess.PIPE,
            text=True,
        )
        assert bare.stdout is not None and bare.stdin is not None
        bare.stdout.readline()
        time.sleep(1.0)
        baseline = _cpu_share(bare.pid, seconds)
        bare.stdin.close()
        bare.wait(15)
        proc, url = _panel([f"g{i}={u}" for i, u in enumerate(urls)])
        try:
            seen: dict[str, set[float]] = {f"g{i}": set() for i in range(4)}
            done = threading.Event()
            port = url.split(":")[2].split("/")[0]

            def read() -> None:
                with connect(f"ws://127.0.0.1:{port}/ws") as ws:
                    while not done.is_set():
                        try:
                            message = json.loads(ws.recv(timeout=0.5))
                        except TimeoutError:
                            continue
                        if message["type"] != "update" or not counting.is_set():
                            continue
                        for snap in message["grippers"]:
                            if snap.get("state"):
                                seen[snap["name"]].add(snap["state"]["t"])

            counting = threading.Event()
            reader = threading.Thread(target=read, daemon=True)
            reader.start()
            time.sleep(1.0)
            counting.set()
            t0 = time.monotonic()
            share = _cpu_share(proc.pid, seconds)
            elapsed = time.monotonic() - t0
            counting.clear()
            done.set()
            reader.join(5)
        finally:
            _stop(proc)
    finally:
        for s in sims:
            s.close()
    rates = {name: len(ts) / elapsed for name, ts in seen.items()}
    slowest = min(rates.values())
    return Result(
        "16 panel: states to a page, 4 grippers",
        f"{share * 100:.1f} % of a core, >= {slowest:.1f} Hz each",
        f"{baseline * 100:.1f} % (bare streams)",
        f"{share / baseline:.2f}x" if baseline > 0 else "-",
        "<= 10 % of a core, >= 20 Hz each",
        share <= 0.10 and slowest >= 20.0,
        [f"per gripper: {', '.join(f'{n} {r:.1f} Hz' for n, r in rates.items())}"],
    )


# -- target 17: a click on Stop to the stop command at the device -------------------------------------------


class _StopLog:
    """A WSG simulator child that prints the monotonic time of every STOP packet it receives."""

    def __init__(self) -> None:
        self.proc = subprocess.Popen(
            [sys.executable, str(Path(__file__).resolve()), "--stop-log"],
            stdin=subprocess.PIPE,
            stdout=subprocess.PIPE,
            text=True,
            cwd=REPO,
        )
        assert self.proc.stdout is not None
        self.url = self.proc.stdout.readline().strip()
        self.times: list[float] = []
        self._reader = threading.Thread(target=self._read, daemon=True)
        self._reader.start()

    def _read(self) -> None:
        assert self.proc.stdout is not None
        for line in self.proc.stdout:
            self.times.append(float(line))

    def close(self) -> None:
        assert self.proc.stdin is not None
        self.proc.stdin.close()
        self.proc.wait(15)


def _stop_log_child() -> None:
    from grippers.drivers.wsg.sim import WsgModel, serve

    server = serve(WsgModel(), "tcp://127.0.0.1:0")
    received = server._received

    def logging_received(link: Any, data: bytes) -> None:
        if STOP in data:
            print(repr(time.monotonic()), flush=True)
        received(link, data)

    server._received = logging_received  # type: ignore[method-assign]
    print(server.url, flush=True)
    sys.stdin.read()
    server.close()


def _clicks(page: Any, button: Any, arrivals: list[float], n: int) -> list[float]:
    """Click ``n`` times; the delay from each click to the next arrival in ``arrivals`` (ms)."""
    box = button.bounding_box()
    x, y = box["x"] + box["width"] / 2, box["y"] + box["height"] / 2
    delays = []
    for _ in range(n):
        before = len(arrivals)
        t0 = time.monotonic()
        page.mouse.click(x, y)
        deadline = t0 + 2.0
        while len(arrivals) == before and time.monotonic() < deadline:
            time.sleep(0.0005)
        if len(arrivals) == before:
            raise RuntimeError("a click reached nothing within 2 s")
        delays.append((arrivals[before] - t0) * 1000)
        time.sleep(0.03)
    return delays


def _p99(values: list[float]) -> float:
    return statistics.quantiles(values, n=100, method="inclusive")[98]


def stop_click(quick: bool) -> Result:
    import uvicorn
    from playwright.sync_api import sync_playwright
    from starlette.applications import Starlette
    from starlette.responses import HTMLResponse
    from starlette.routing import Route, WebSocketRoute

    n = 40 if quick else 200
    arrivals: list[float] = []

    async def page(request: Any) -> HTMLResponse:
        return HTMLResponse(_BARE_PAGE)

    async def ws(socket: Any) -> None:
        from starlette.websockets import WebSocketDisconnect

        await socket.accept()
        try:
            while True:
                await socket.receive_text()
                arrivals.append(time.monotonic())
        except WebSocketDisconnect:
            pass

    bare = uvicorn.Server(
        uvicorn.Config(
            Starlette(routes=[Route("/", page), WebSocketRoute("/ws", ws)]), port=0, log_level="warning"
        )
    )
    import socket as socket_module

    sock = socket_module.socket()
    sock.bind(("127.0.0.1", 0))
    thread = threading.Thread(target=bare.run, kwargs={"sockets": [sock]}, daemon=True)
    thread.start()
    while not bare.started:
        time.sleep(0.01)
    sim = _StopLog()
    proc, url = _panel([f"left={sim.url}"])
    try:
        with sync_playwright() as p:
            browser = p.chromium.launch(executable_path=CHROMIUM, args=["--no-sandbox"])
            tab = browser.new_page()
            tab.goto(f"http://127.0.0.1:{sock.getsockname()[1]}/")
            tab.wait_for_function("document.title === 'open'")
            base = _clicks(tab, tab.locator("#b"), arrivals, n)
            tab.goto(url)
            tab.get_by_text("connected as page").wait_for()
            stop = tab.get_by_role("region", name="left").get_by_role("button", name="Stop", exact=True)
            figure = _clicks(tab, stop, sim.times, n)
            browser.close()
    finally:
        _stop(proc)
        sim.close()
        bare.should_exit = True
        thread.join(5)
        sock.close()
    p99, b99 = _p99(figure), _p99(base)
    return Result(
        "17 panel: click on Stop to the device (p99)",
        f"{p99:.1f} ms",
        f"{b99:.1f} ms (bare page)",
        f"{p99 / b99:.2f}x",
        "<= 50 ms",
        p99 <= 50.0,
        [f"median {statistics.median(figure):.1f} ms vs {statistics.median(base):.1f} ms, {n} clicks each"],
    )


def run(quick: bool) -> list[Result]:
    return [state_load(quick), stop_click(quick)]


__all__ = ["run", "state_load", "stop_click"]


if __name__ == "__main__":
    ap = argparse.ArgumentParser()
    ap.add_argument("--stop-log", action="store_true", help="(internal) the simulator child of target 17")
    ap.add_argument("--quick", action="store_true")
    args = ap.parse_args()
    if args.stop_log:
        _stop_log_child()
    else:
        from benchmarks.common import format_table

        print(format_table(run(args.quick)))
