"""What ``grippers sim wsg`` and ``grippers sim msg`` share: options, and serving until interrupted."""

from __future__ import annotations

import argparse
import signal
import sys
import threading
from typing import Any

from .common import non_negative_float, positive_float


def add_sim_arguments(parser: argparse.ArgumentParser, default_profile: str, listen_help: str) -> None:
    parser.add_argument("--listen", metavar="WHERE", help=listen_help)
    parser.add_argument(
        "--profile", default=default_profile, help=f"device profile (default {default_profile})"
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


class _Terminated(Exception):
    """Raised by the SIGTERM handler in the main thread, so the wait ends at once (a flag would only be seen
    when the wait's timeout runs out: Python retries an interrupted wait, PEP 475)."""


def warn_private_bus(listen: str) -> None:
    """python-can's ``virtual`` bus lives in one process: a client in another shell would wait for answers
    that never come, so say so before serving."""
    if listen.startswith("can://virtual"):
        print(
            "grippers sim: warning: python-can's virtual bus exists only inside this process; no other "
            "process can reach it (use can://udp_multicast/239.74.163.2 or can://socketcan/vcan0)",
            file=sys.stderr,
            flush=True,
        )


def serve_forever(server: Any, what: str, urls: list[str] | None = None) -> int:
    """Print where to connect (first line, for people and for scripts; one line per extra node), then serve
    until Ctrl-C (exit 130, like every command) or SIGTERM (exit 0)."""

    def _terminate(*_: object) -> None:
        raise _Terminated

    previous = signal.signal(signal.SIGTERM, _terminate)
    urls = urls or [server.url]
    try:
        print(f"{what} serving at {urls[0]}", flush=True)
        for url in urls[1:]:
            print(f"  also at {url}", flush=True)
        print("press Ctrl-C to stop", file=sys.stderr, flush=True)
        threading.Event().wait()  # forever; the signal handlers end it
    except _Terminated:
        return 0
    finally:
        signal.signal(signal.SIGTERM, previous)
        server.close()
    return 0  # pragma: no cover - the wait above only ends by an exception


def settings_for(profile: Any, args: argparse.Namespace, **extra: Any) -> Any:
    from grippers.settings import Settings

    values: dict[str, Any] = {"time_scale": args.time_scale, "part_width_mm": args.part_width, **extra}
    return Settings(f"sim://{profile.name}", {}, {k: v for k, v in values.items() if v is not None})
