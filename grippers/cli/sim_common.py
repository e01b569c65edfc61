"""What every family's ``grippers sim FAMILY`` shares: options, replaying a capture, serving until stopped."""

from __future__ import annotations

import argparse
import errno
import re
import signal
import sys
from collections.abc import Callable
from typing import Any

from . import signals
from .common import non_negative_float, positive_float


def add_sim_arguments(
    parser: argparse.ArgumentParser, default_profile: str | None, listen_help: str, *, replay: bool = True
) -> None:
    parser.add_argument("--listen", metavar="WHERE", help=listen_help)
    parser.add_argument(
        "--profile",
        "--model",
        dest="profile",
        default=default_profile,
        metavar="NAME",
        help=f"device profile, by name, alias or file (default {default_profile or 'the family default'})",
    )
    parser.add_argument(
        "--time-scale",
        type=positive_float,
        default=1.0,
        metavar="N",
        help="simulated seconds per wall-clock second (default 1; tests use 20-100)",
    )
    parser.add_argument(
        "--part-width",
        type=non_negative_float,
        default=None,
        metavar="MM",
        help="width of a part between the fingers in mm (default: no part)",
    )
    if replay:
        parser.add_argument(
            "--replay",
            metavar="FILE",
            help="answer as the captured session did (a capture saved by grippers monitor --write); a "
            "request that differs from the capture is reported on stderr and not answered",
        )
    parser.add_argument(
        "--json",
        action="store_true",
        help="print where to connect as one JSON document (schema grippers.sim/1) instead of the sentence",
    )


SIM_SCHEMA_ID = "grippers.sim/1"


def bind_error(exc: OSError, listen: str) -> str:
    """One line saying why a listening socket could not be opened, and what to do instead."""
    free = re.sub(r":\d+$", ":0", listen)
    if exc.errno in (errno.EACCES, errno.EPERM):
        return (
            f"cannot listen on {listen}: ports below 1024 need root (or CAP_NET_BIND_SERVICE); "
            f"--listen {free} picks a free port"
        )
    if exc.errno == errno.EADDRINUSE:
        return (
            f"cannot listen on {listen}: the port is in use (another simulator?); --listen {free} picks one"
        )
    return f"cannot listen on {listen}: {exc.strerror or exc}"


def start_server(start: Callable[[str], Any], listen: str | None, default: str) -> Any:
    """Start a server on ``listen`` or on ``default``, the device's real port.

    A user who did not ask for a port gets one that works: when the default is refused for want of root (the
    WSG's port 1000 is privileged), the simulator serves on a free port and says so on one line. A port the
    user named is never changed: its failure is one line with the fix.
    """
    where = listen or default
    try:
        return start(where)
    except OSError as exc:
        if listen is None and exc.errno in (errno.EACCES, errno.EPERM):
            free = re.sub(r":\d+$", ":0", default)
            print(
                f"grippers sim: warning: {default} needs root (ports below 1024); serving on a free port "
                f"instead (--listen {free})",
                file=sys.stderr,
                flush=True,
            )
            try:
                return start(free)
            except OSError as again:
                raise OSError(bind_error(again, free)) from None
        raise OSError(bind_error(exc, where)) from None


class _Terminated(Exception):
    """Raised by the SIGTERM handler in the main thread, so the wait ends at once (a flag would only be seen
    when the wait's timeout runs out: Python retries an interrupted wait, PEP 475)."""


def warn_private_bus(listen: str) -> None:
    """python-can's ``virtual`` bus lives in one process: a client in another shell would wait for answers
    that never come, so say so before serving."""
    from grippers.urls import URLError, parse_url

    try:
        url = parse_url(listen, bare_family="sim", listen=True)
    except URLError:
        return  # serving it says what is wrong
    if url.transport == "can" and url.interface == "virtual":
        print(
            "grippers sim: warning: python-can's virtual bus exists only inside this process; no other "
            "process can reach it (use can://udp_multicast/239.74.163.2 or can://socketcan/vcan0)",
            file=sys.stderr,
            flush=True,
        )


def _wait_for_a_signal() -> None:
    """Block until a signal's Python handler raises (SIGTERM, Ctrl-C).

    A process-directed signal may be taken by any thread (the servers' threads here); the main thread, blocked
    in a lock as ``threading.Event().wait()`` blocks it, is then never woken to run the handler, and the
    simulator ignored SIGTERM for good (seen under load in CI). The wakeup fd is written by whichever thread
    takes the signal, so the main thread's ``select`` returns and Python runs the handler."""
    import os
    import select

    read_fd, write_fd = os.pipe()
    os.set_blocking(write_fd, False)
    previous = signal.set_wakeup_fd(write_fd, warn_on_full_buffer=False)
    try:
        while True:
            select.select([read_fd], [], [])
            os.read(read_fd, 512)  # a signal without a raising handler: drain and wait on
    finally:
        signal.set_wakeup_fd(previous)
        os.close(read_fd)
        os.close(write_fd)


HOLD_SIGNAL = signal.SIGUSR1
"""``kill -USR1`` holds a running ``grippers sim``'s simulated clock still (the jaws stop where they are, the
device goes on answering); ``kill -USR2`` (:data:`RUN_SIGNAL`) lets it run again. Each is confirmed by a line
on stderr ("grippers sim: clock held" / "... running") once it took effect, so a test in another process can
act on a device it knows is still (the rule of docs/reliability.md: never race the simulator's clock)."""
RUN_SIGNAL = signal.SIGUSR2
HOLD_CREEP_S = 0.001
"""Simulated seconds each reading of a held clock moves it on: frames reach a real device apart in time, and
the MSG's firmware tells a poll within one control tick (160-200 us) of a new command apart from a later one
(drivers/simkit.py, ``SimClock.pause``); 1 ms per reading moves a 20 mm/s jaw 0.02 mm."""


def _hold_on_signals(server: Any) -> list[tuple[int, Any]]:
    """Install the hold/run handlers where the server has one scaled clock; returns what to restore."""
    clock = getattr(server, "clock", None)
    if clock is None or not hasattr(clock, "pause"):
        return []

    def hold(*_: object) -> None:
        clock.pause(creep=HOLD_CREEP_S)
        print("grippers sim: clock held", file=sys.stderr, flush=True)

    def run(*_: object) -> None:
        clock.resume()
        print("grippers sim: clock running", file=sys.stderr, flush=True)

    return [(HOLD_SIGNAL, signal.signal(HOLD_SIGNAL, hold)), (RUN_SIGNAL, signal.signal(RUN_SIGNAL, run))]


def serve_forever(server: Any, what: str, urls: list[str] | None = None, *, as_json: bool = False) -> int:
    """Print where to connect (first line, for people and for scripts; one line per extra node; with --json
    one document ``{"schema": "grippers.sim/1", "what": ..., "urls": [...]}``), then serve until Ctrl-C (exit
    130, like every command) or SIGTERM (exit 0)."""

    def _terminate(*_: object) -> None:
        raise _Terminated

    previous = signals.ends_service(_terminate)  # SIGTERM and SIGHUP: exit 0 (grippers/cli/signals.py)
    held = _hold_on_signals(server)
    urls = urls or [server.url]
    try:
        if as_json:
            from .output import write_json

            write_json({"schema": SIM_SCHEMA_ID, "what": what, "urls": urls})
        else:
            print(f"{what} serving at {urls[0]}", flush=True)
            for url in urls[1:]:
                print(f"  also at {url}", flush=True)
        _wait_for_a_signal()  # forever; the signal handlers end it
    except _Terminated:
        return 0
    finally:
        signals.restore(previous)
        for sig, handler in held:
            signal.signal(sig, handler)
        server.close()
    return 0  # pragma: no cover - the wait above only ends by an exception


def serve_replay(args: argparse.Namespace, start: Callable[[bytes], tuple[Any, Any]]) -> int:
    """``--replay FILE``: serve the capture instead of a simulated device; exit 1 if a request mismatched.

    ``start(blob)`` is the family's: it reads its capture into a script and starts the server that answers
    from it (a CaptureError or ValueError is the command line's fault)."""
    from grippers.drivers.captures import CaptureError
    from grippers.drivers.replay import summary

    from .output import UsageError

    try:
        with open(args.replay, "rb") as fh:
            blob = fh.read()
    except OSError as exc:
        raise UsageError(f"--replay {args.replay}: {exc.strerror or exc}") from None
    try:
        server, script = start(blob)
    except (CaptureError, ValueError) as exc:
        raise UsageError(f"--replay {args.replay}: {exc}") from None
    try:
        code = serve_forever(server, f"replay of {args.replay}", as_json=args.json)
    finally:
        print(summary(script), file=sys.stderr, flush=True)
    return 1 if script.mismatches else code


def settings_for(profile: Any, args: argparse.Namespace, **extra: Any) -> Any:
    from grippers.settings import Settings

    values: dict[str, Any] = {"time_scale": args.time_scale, "part_width_mm": args.part_width, **extra}
    return Settings(f"sim://{profile.name}", {}, {k: v for k, v in values.items() if v is not None})
