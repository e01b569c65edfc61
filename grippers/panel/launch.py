"""Starting the panel from the command line: its options and the served set's panel.

Shared by ``grippers panel`` (grippers/cli/panel.py) and ``grippers serve --http`` (grippers/cli/serve.py).
Nothing heavy at module level: ``serve --help`` and ``panel --help`` import this, and the web stack (the
``panel`` extra) loads only when a panel starts.
"""

from __future__ import annotations

import argparse
from typing import Any


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
    from grippers.cli.output import UsageError
    from grippers.errors import URLError

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
