"""``grippers panel [NAME=]URL ...``: watch and drive grippers from a web page (docs/panel.md).

Starlette and uvicorn (the ``panel`` extra) are imported inside ``run`` only: ``grippers --help`` stays
fast.
"""

from __future__ import annotations

import argparse
import signal
import sys
import threading
from typing import Any

HELP = "serve a web page that shows and drives grippers (the panel extra; loopback unless --listen)"
EXAMPLE = (
    "grippers panel sim://wsg50\n"
    "         grippers panel left=wsg+tcp://192.168.1.20 right=zenoh://right?connect=tcp/127.0.0.1:7447\n"
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


def add_http_arguments(parser: argparse.ArgumentParser, flag: str, help_text: str) -> None:
    """The panel's options (``panel --listen``, ``serve --http``): where, the token, TLS."""
    parser.add_argument(flag, dest="http", metavar="HOST:PORT", default=None, help=help_text)
    parser.add_argument(
        "--token",
        default=None,
        help="the token every request must carry (default: none on loopback, a new one elsewhere, printed)",
    )
    parser.add_argument("--tls-cert", metavar="FILE", help="serve HTTPS with this certificate (PEM)")
    parser.add_argument("--tls-key", metavar="FILE", help="the certificate's private key (PEM)")


def start_panel(args: argparse.Namespace, grippers: dict[str, Any], listen: str) -> Any:
    """A started :class:`~grippers.panel.server.PanelServer` for the options (UsageError on bad ones)."""
    from grippers.errors import URLError

    from .output import UsageError

    try:
        from grippers.panel.server import PanelServer
    except ImportError as exc:
        raise UsageError(
            f"the panel needs the panel extra: pip install 'grippers[panel]' ({exc.name} is missing)"
        ) from None
    if (args.tls_cert is None) != (args.tls_key is None):
        raise UsageError("--tls-cert and --tls-key go together")
    try:
        server = PanelServer(
            grippers, listen=listen, token=args.token, certfile=args.tls_cert, keyfile=args.tls_key
        )
    except URLError as exc:
        raise UsageError(exc.message) from None
    return server.start()


def run(args: argparse.Namespace) -> int:
    import grippers

    from .output import UsageError, write_json
    from .serve import parse_targets

    opened: dict[str, Any] = {}
    server = None
    stop = threading.Event()
    signal.signal(signal.SIGTERM, lambda *_: stop.set())
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
    return 0


class ServedPanel:
    """``grippers serve ... --http HOST:PORT``: the panel over the served grippers, as clients of the server.

    The page drives each gripper through its ``zenoh://`` URL on this very server, never through the opened
    device: a program that holds a gripper's lease keeps it (the page is refused, naming the holder), and
    the page's own control takes the lease like any client's (its label ``panel``)."""

    def __init__(self, args: argparse.Namespace, server: Any, names: list[str]) -> None:
        import grippers

        self.clients: dict[str, Any] = {}
        self.panel: Any = None
        try:
            for name in names:
                url = server.url(name)
                self.clients[name] = grippers.open(f"{url}{'&' if '?' in url else '?'}label=panel")
            self.panel = start_panel(args, self.clients, args.http)
        except BaseException:
            self.close()
            raise

    @property
    def url(self) -> str:
        return str(self.panel.url)

    def close(self) -> None:
        if self.panel is not None:
            self.panel.close()
        for client in self.clients.values():
            client.close()
