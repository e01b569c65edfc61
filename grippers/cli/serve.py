"""``grippers serve NAME=TARGET ...``: share grippers with other processes and machines over Eclipse Zenoh.

The key space and payloads are in docs/remote.md. Zenoh is imported inside ``run`` only (the ``remote``
extra).
"""

from __future__ import annotations

import argparse
import logging
import signal
import sys
import threading
from typing import Any

from . import signals
from .common import positive_float

HELP = "serve grippers over Eclipse Zenoh (zenoh://NAME URLs for other processes and machines)"
EXAMPLE = (
    "grippers serve left=sim:// right='sim://?time_scale=10'\n"
    "         grippers serve left=FAMILY+tcp://192.168.1.20 right=sim://   (your gripper's URL)\n"
    "         grippers serve PROFILE --listen tcp/0.0.0.0:7447        (every interface: other machines)\n"
    "         grippers serve left=PROFILE --zenoh-config cell.json5   (TLS, access control, routers)"
)


def add_arguments(parser: argparse.ArgumentParser) -> None:
    parser.add_argument(
        "targets",
        nargs="+",
        metavar="[NAME=]TARGET",
        help="a URL, profile name or profile file to open and serve as NAME (default: its profile's name)",
    )
    parser.add_argument(
        "--listen",
        action="append",
        metavar="ENDPOINT",
        help="Zenoh endpoint to listen on, repeatable (default tcp/127.0.0.1:7447: loopback only; port 0 "
        "picks a free port)",
    )
    parser.add_argument(
        "--connect", action="append", metavar="ENDPOINT", help="a router or peer to connect to"
    )
    parser.add_argument(
        "--json", action="store_true", help="print what is served where as one JSON document (docs/cli.md)"
    )
    parser.add_argument(
        "--zenoh-config", metavar="FILE", help="a Zenoh JSON5 configuration (TLS, ACL, routers)"
    )
    parser.add_argument(
        "--scout",
        action="store_true",
        help="enable Zenoh multicast scouting (off: nothing announced on the LAN)",
    )
    parser.add_argument(
        "--rate",
        type=positive_float,
        default=50.0,
        metavar="HZ",
        help="state publications per second (default 50)",
    )
    parser.add_argument(
        "--lease-timeout",
        type=positive_float,
        default=1.0,
        metavar="SECONDS",
        help="stop the motion of a controlling client that vanished or went silent within this long, "
        "whatever Zenoh lease it announced (default 1)",
    )
    from grippers.panel.launch import add_http_arguments  # --http HOST:PORT, --token, --tls-*: docs/panel.md

    add_http_arguments(parser, "--http", "also serve the panel (docs/panel.md) on HOST:PORT (port 0: free)")
    parser.add_argument(
        "--log-file",
        metavar="PATH",
        help="write the log (time stamp, level, message) to PATH instead of stderr (appended)",
    )
    parser.add_argument(
        "-t",
        "--timeout",
        type=positive_float,
        default=None,
        metavar="SECONDS",
        help="device exchange timeout",
    )


LOG_FORMAT = "%(asctime)s %(levelname)s %(name)s: %(message)s"


def start_logging(path: str | None) -> logging.Handler:
    """serve runs for days: its lines (a gripper lost or back, a holder gone, a lease freed) carry a time
    stamp and a level, go to stderr (stdout holds the URLs scripts read) or to ``--log-file``, at INFO."""
    from .output import UsageError

    if path:
        try:
            handler: logging.Handler = logging.FileHandler(path, encoding="utf-8")
        except OSError as exc:
            raise UsageError(f"--log-file {path}: {exc.strerror or exc}") from None
    else:
        handler = logging.StreamHandler(sys.stderr)
    handler.setFormatter(logging.Formatter(LOG_FORMAT))
    root = logging.getLogger("grippers")
    for cli_handler in [h for h in root.handlers if getattr(h, "_grippers_cli", False)]:
        root.removeHandler(cli_handler)  # serve's handler takes over: with --log-file nothing goes to stderr
    root.addHandler(handler)
    if root.level == logging.NOTSET or root.level > logging.INFO:
        root.setLevel(logging.INFO)
    return handler


def parse_targets(items: list[str]) -> list[tuple[str | None, str]]:
    """``NAME=TARGET`` or a bare ``TARGET``; a URL's own ``=`` (in its query) is not a name, nor is one in
    the path of a file that exists. Anything else before the first ``=`` is a name, checked as one: ``a/b=``,
    ``x?y=sim://wsg50`` and a name ending in a newline are refused with a message about the served name
    (issue 43 §3: they got one about a scheme, or were served under a key ending in a newline)."""
    from pathlib import Path

    from grippers.urls import is_url

    out: list[tuple[str | None, str]] = []
    for item in items:
        head, eq, tail = item.partition("=")
        setting = "?" in head and not is_url(tail) and not Path(tail).suffix  # PROFILE?setting=value
        if not eq or is_url(head) or setting or Path(item).exists():
            out.append((None, item))
        else:
            out.append((head, tail))
    return out


def run(args: argparse.Namespace) -> int:
    import grippers
    from grippers.drivers.urls import check_endpoints
    from grippers.errors import URLError
    from grippers.remote import protocol
    from grippers.remote.server import Server

    from .output import UsageError, write_json

    try:  # a mistyped endpoint is a usage error, said before any gripper opens (issue 33 §3)
        check_endpoints(args.listen or [], "--listen")
        check_endpoints(args.connect or [], "--connect")
    except URLError as exc:
        raise UsageError(exc.message) from None
    targets = parse_targets(args.targets)
    for name, target in targets:
        if name is not None:
            try:
                protocol.check_name(name)
            except ValueError as exc:
                raise UsageError(str(exc)) from None
        if not target:
            raise UsageError(f"nothing to serve as {name!r}")
    opened: dict[str, Any] = {}
    stop = threading.Event()
    ended_by: list[str] = []

    def end(signum: int, frame: object) -> None:
        ended_by.append(signal.Signals(signum).name)
        stop.set()

    previous = signals.ends_service(end)  # SIGTERM and SIGHUP: the same stops as Ctrl-C, then exit 0
    server = panel = None
    handler = start_logging(args.log_file)
    log = logging.getLogger("grippers.remote")
    try:
        for name, target in targets:
            kwargs = {} if args.timeout is None else {"timeout": args.timeout}
            gripper = grippers.open(target, **kwargs)
            served = name or gripper.profile.name
            if served in opened:
                gripper.close()
                raise UsageError(f"two grippers named {served!r}: write NAME=TARGET")
            opened[served] = gripper
        try:
            server = Server(
                opened,
                listen=args.listen,
                connect=args.connect,
                config_file=args.zenoh_config,
                scout=args.scout,
                rate=args.rate,
                lease_timeout=args.lease_timeout,
            )
        except ValueError as exc:
            raise UsageError(str(exc)) from None
        server.start()
        if args.http:
            from grippers.panel.launch import ServedPanel

            panel = ServedPanel(args, server, list(opened))
        if args.json:
            listing = [
                {"name": n, "model": g.profile.model, "target": g.url, "url": server.url(n)}
                for n, g in opened.items()
            ]
            panel_url = {"panel": panel.url} if panel is not None else {}
            write_json({"schema": "grippers.serve/1", "grippers": listing, **panel_url})
        for name, gripper in opened.items():
            if not args.json:
                print(
                    f"{name}: {gripper.profile.model} at {gripper.url} serving at {server.url(name)}",
                    flush=True,
                )
            log.info(
                "serving %s (%s at %s) at %s", name, gripper.profile.model, gripper.url, server.url(name)
            )
        if panel is not None and not args.json:
            print(f"panel at {panel.url}", flush=True)
        print("press Ctrl-C to stop", file=sys.stderr, flush=True)
        while not stop.wait(0.5):
            pass
        log.info("%s: withdrawing and closing", ended_by[0] if ended_by else "SIGTERM")
    finally:
        # Ctrl-C leaves through here too: the CLI's own handler then says "interrupted" and exits 130.
        if panel is not None:
            panel.close()
        if server is not None:
            server.close()  # closes every gripper
        else:
            for gripper in opened.values():
                gripper.close()
        logging.getLogger("grippers").removeHandler(handler)
        handler.close()
        signals.restore(previous)
    return 0
