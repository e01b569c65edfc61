"""``grippers panel [NAME=]URL ...``: watch and drive grippers from a web page (docs/panel.md).

Starlette and uvicorn (the ``panel`` extra) are imported inside ``run`` only: ``grippers --help`` stays
fast.
"""

from __future__ import annotations

import argparse
import sys
import threading
from typing import Any

from grippers.panel.launch import add_http_arguments, start_panel

from . import signals

HELP = "serve a web page that shows and drives grippers (the panel extra; loopback unless --listen)"
EXAMPLE = (
    "grippers panel sim://PROFILE\n"
    "         grippers panel left=FAMILY+tcp://192.168.1.20 right=zenoh://right?connect=tcp/127.0.0.1:7447\n"
    "         grippers panel PROFILE --listen 0.0.0.0:8000       (other machines: a token is printed)"
)


def add_arguments(parser: argparse.ArgumentParser) -> None:
    parser.add_argument(
        "targets",
        nargs="+",
        metavar="[NAME=]URL",
        help="a URL, profile name or profile file to open and show as NAME (default: its profile's name)",
    )
    add_http_arguments(parser, "--listen", "where to serve the page (default 127.0.0.1:0: a free port)")
    parser.add_argument("--json", action="store_true", help='print {"url": ...} as the first line of stdout')
    parser.add_argument("--open", action="store_true", help="open the page in the default browser")
    parser.add_argument("-t", "--timeout", type=float, default=None, metavar="SECONDS", help="device timeout")


def run(args: argparse.Namespace) -> int:
    import grippers

    from .output import UsageError, write_json
    from .serve import parse_targets

    opened: dict[str, Any] = {}
    server = None
    stop = threading.Event()
    previous = signals.ends_service(lambda *_: stop.set())  # SIGTERM, SIGHUP: stop the jaws, exit 0
    try:
        for name, target in parse_targets(args.targets):
            kwargs = {} if args.timeout is None else {"timeout": args.timeout}
            gripper = grippers.open(target, **kwargs)
            shown = name or gripper.profile.name
            if shown in opened:
                gripper.close()
                raise UsageError(f"two grippers named {shown!r}: write NAME=URL")
            opened[shown] = gripper
        server = start_panel(args, opened, args.http or "127.0.0.1:0")
        if args.json:
            write_json({"url": server.url})
        else:
            print(f"panel at {server.url}", flush=True)
        print("press Ctrl-C to stop", file=sys.stderr, flush=True)
        if args.open:
            import webbrowser

            webbrowser.open(server.url)
        while not stop.wait(0.5):
            pass
    finally:
        # Ctrl-C leaves through here: pages are disconnected (their motions stopped), then grippers closed.
        if server is not None:
            server.close()
        for gripper in opened.values():
            gripper.close()
        signals.restore(previous)
    return 0
