"""``grippers monitor``: decode live traffic or a capture into one readable line per frame or packet.

Sources: a capture file (candump log for CAN; hex dump or raw bytes for a byte protocol; ``-`` reads stdin,
so ``candump -L can0 | grippers monitor -`` works), a live CAN bus (``-i``/``-c``), or a live TCP connection
through ``--proxy``. The decoding is the families' own (each backend's ``dissector`` hook hands over its
driver's packet parser and command table), so the monitor shows exactly what the clients and simulators
understand, and there is no second copy of any byte layout here.
"""

from __future__ import annotations

import argparse
import itertools
import sys
import time
from collections.abc import Callable, Iterator
from typing import IO, Any

from .common import add_can_flags, can_id, positive_float
from .output import EXIT_FAILED, EXIT_OK, MONITOR_SCHEMA_ID, UsageError, write_json

HELP = "decode live CAN traffic, a TCP connection (--proxy) or a capture, one line per frame or packet"
EXAMPLE = (
    "grippers monitor capture.log            (candump -L format)\n"
    "         grippers monitor session.hex --protocol FAMILY\n"
    "         grippers monitor -i socketcan -c can0 --protocol FAMILY\n"
    "         grippers monitor FAMILY+can://socketcan/can0       (the URL the other commands take)\n"
    "         grippers monitor FAMILY+tcp://192.168.1.20         (through a proxy on a free port)\n"
    "         grippers monitor --proxy 127.0.0.1:1000 --to 192.168.1.20:1000\n"
    "         candump -L can0 | grippers monitor -\n"
    "         grippers monitor -i socketcan -c can0 -t r --write session.log   (record a fixture)"
)

FORMATS = ("auto", "candump", "hex", "raw")
# The longest line a text capture may have: a --proxy --write line holds one 64 KiB read, 128 KiB of hex. A
# longer one is not a capture (``monitor /dev/zero`` read 7.9 GB looking for the first line end, issue 33 §3).
MAX_LINE = 1 << 20
CHUNK = 1 << 16  # a raw capture is decoded in pieces of this size, as they arrive


def _host_port(text: str) -> tuple[str, int]:
    from grippers.drivers.urls import URLError, parse_address

    try:
        host, port = parse_address(text, listen=True)  # the one grammar: drivers/urls.py
    except URLError:
        host, port = None, -1
    if host is None:
        raise argparse.ArgumentTypeError(f"expected HOST:PORT, not {text!r}")
    return host, port


def add_arguments(parser: argparse.ArgumentParser) -> None:
    parser.add_argument(
        "capture",
        nargs="?",
        metavar="FILE|URL",
        help="capture file, or - for stdin; or a URL: can://IF/CH, FAMILY+can://IF/CH (a live bus, like "
        "-i/-c), FAMILY+tcp://HOST[:PORT] (through the proxy); omit with -i/-c or --proxy",
    )
    parser.add_argument("--format", choices=FORMATS, default="auto", help="capture format (default: detect)")
    parser.add_argument(
        "--protocol",
        default="auto",
        metavar="NAME",
        help="decode with this family's or protocol's dissector (an installed family's name; default: "
        "every installed family's, each CAN frame by the family that claims it; bytes by the family that "
        "reads byte captures by default)",
    )
    parser.add_argument(
        "--can-id",
        type=can_id,
        default=0x000,
        metavar="ID",
        help="for a family that sends commands on a CAN id and replies on the next: the command id "
        "(default 0x000, docs/protocols.md)",
    )
    parser.add_argument(
        "--direction",
        choices=("to", "from", "unknown"),
        default="unknown",
        help="for byte captures without direction marks: bytes sent to (to) or from (from) the gripper",
    )
    parser.add_argument(
        "--json", action="store_true", help="JSON Lines, one object per frame or packet (see docs/cli.md)"
    )
    parser.add_argument("-n", "--count", type=int, default=0, metavar="N", help="stop after N decoded lines")
    parser.add_argument(
        "--duration",
        type=positive_float,
        metavar="SECONDS",
        help="live: stop after this long (default: Ctrl-C)",
    )
    parser.add_argument(
        "--proxy",
        type=_host_port,
        metavar="HOST:PORT",
        help="live over TCP: listen here (port 0: a free port, printed on stderr), forward to --to",
    )
    parser.add_argument(
        "--to", type=_host_port, metavar="HOST:PORT", help="with --proxy: the gripper to forward to"
    )
    parser.add_argument(
        "-t",
        "--timestamps",
        choices=("a", "r", "z", "d"),
        default="a",
        metavar="TYPE",
        help="time column, as candump's -t: a absolute (default), r or z relative to the first line, "
        "d delta to the previous line",
    )
    parser.add_argument(
        "--write",
        metavar="FILE",
        help="live sources: also save the traffic, a candump log (-L format) for CAN, a timestamped hex "
        "dump with directions for --proxy; both are read back by monitor and by sim --replay",
    )
    add_can_flags(parser)


# --- sources -----------------------------------------------------------------------------------------------


class _Capture:
    """A capture file, or stdin for ``-``, read as it arrives: a text capture line by line (each at most
    :data:`MAX_LINE` bytes), raw bytes in pieces. So ``candump -L can0 | grippers monitor -`` shows each frame
    when candump writes it, and memory stays bounded whatever comes in (before, all of stdin was read first).

    The format (``--format auto``) is decided on the first line that is neither blank nor a comment; the
    lines read for that are handed out again first."""

    def __init__(self, name: str) -> None:
        self.name = name
        self._head: list[bytes] = []
        self._lines = 0
        if name == "-":
            self._fh: IO[bytes] = sys.stdin.buffer
            self._owned = False
            return
        try:
            self._fh = open(name, "rb")  # noqa: SIM115 - closed by close(), from the caller's finally
        except OSError as exc:
            raise UsageError(f"cannot read {name}: {exc.strerror or exc}") from None
        self._owned = True

    def close(self) -> None:
        if self._owned:
            self._fh.close()

    def _readline(self) -> bytes:
        self._lines += 1
        return self._fh.readline(MAX_LINE + 1)

    def _too_long(self, number: int) -> UsageError:
        return UsageError(
            f"{self.name}: line {number} is longer than {MAX_LINE} bytes: not a candump log or a hex dump "
            "(raw bytes: --format raw)"
        )

    def sniff(self) -> str:
        """'candump', 'hex' or 'raw' from the first significant line, as :func:`sniff_format` decides."""
        from grippers.drivers.captures import looks_like_text, sniff_format

        held = 0
        while held <= MAX_LINE:  # blank lines and comments before the first record: bounded too
            line = self._readline()
            self._head.append(line)
            held += len(line)
            if not line:
                break
            if not looks_like_text(line):
                if len(line) > MAX_LINE and not _holds_a_packet(line):
                    raise UsageError(
                        f"{self.name}: not a capture: no line end in the first {MAX_LINE} bytes, and no "
                        "packet of an installed family in them (raw bytes anyway: --format raw)"
                    )
                return "raw"
            if len(line) > MAX_LINE:
                raise self._too_long(self._lines)
            text = line.strip()
            if text and not text.startswith(b"#"):
                break
        return sniff_format(b"".join(self._head))

    def lines(self) -> Iterator[str]:
        """The capture's lines as text, the sniffed ones first; an over-long line is a UsageError."""
        head, self._head = self._head, []
        for number, line in enumerate(itertools.chain(head, iter(self._readline, b"")), start=1):
            if len(line) > MAX_LINE:
                raise self._too_long(number)
            yield line.decode("ascii", errors="replace").rstrip("\r\n")

    def chunks(self) -> Iterator[bytes]:
        """The capture's bytes in pieces as they arrive (``read1``: what is there, not waiting for more)."""
        head, self._head = self._head, []
        read1 = getattr(self._fh, "read1", self._fh.read)
        yield from (piece for piece in head if piece)
        yield from iter(lambda: read1(CHUNK), b"")


def _holds_a_packet(data: bytes) -> bool:
    """Whether any installed family's byte dissector finds one of its packets in ``data``."""
    return any(d.finds(data) for d in dict.fromkeys(dissectors().values()) if d.finds is not None)


def _capture_records(args: argparse.Namespace) -> Iterator[dict[str, Any]]:
    from grippers.drivers.captures import (
        FROM_DEVICE,
        TO_DEVICE,
        UNKNOWN_DIRECTION,
        CaptureError,
        parse_candump,
        parse_hex_dump,
    )

    capture = _Capture(args.capture)
    try:
        fmt = args.format if args.format != "auto" else capture.sniff()
        if fmt == "candump":
            decoder = can_decoder(args)
            for frame in parse_candump(capture.lines()):
                yield from decoder.decode(
                    frame.arbitration_id,
                    frame.data,
                    frame.is_remote,
                    frame.timestamp,
                    is_extended=frame.is_extended,
                    is_fd=frame.is_fd,
                    is_error=frame.is_error,
                )
            yield from decoder.flush()
            return
        default = {"to": TO_DEVICE, "from": FROM_DEVICE}.get(args.direction, UNKNOWN_DIRECTION)
        stream = byte_stream(args)
        if fmt == "raw":
            for piece in capture.chunks():
                yield from stream.feed(default, piece, None)
        else:
            for chunk in parse_hex_dump(capture.lines(), default):
                yield from stream.feed(chunk.direction, chunk.data, chunk.timestamp)
        yield from stream.flush()
    except CaptureError as exc:
        raise UsageError(f"{args.capture}: {exc}") from None
    finally:
        capture.close()


def _live_can_records(args: argparse.Namespace, writer: Writer | None) -> Iterator[dict[str, Any]]:
    import can

    from grippers.drivers.captures import format_candump

    if not (args.interface and args.channel):
        raise UsageError(
            "live monitoring needs both -i/--interface and -c/--channel (or give a capture FILE)"
        )
    kwargs: dict[str, Any] = {"interface": args.interface, "channel": args.channel}
    if args.bitrate:
        kwargs["bitrate"] = args.bitrate
    if getattr(args, "bus_port", None) is not None:  # ?port= of the URL (apply_url)
        kwargs["port"] = args.bus_port
    end = None if args.duration is None else time.monotonic() + args.duration
    with can.Bus(**kwargs) as bus:
        # The dissectors load the families' code (~0.3 s): the open bus holds what arrives meanwhile.
        decoder = can_decoder(args)
        while end is None or time.monotonic() < end:
            wait = 0.25 if end is None else max(0.0, min(0.25, end - time.monotonic()))
            msg = bus.recv(timeout=wait)
            if msg is None:
                continue
            stamp = msg.timestamp or time.time()
            data = bytes(msg.data)
            flags = {
                "is_extended": bool(msg.is_extended_id),
                "is_fd": bool(msg.is_fd),
                "is_error": bool(msg.is_error_frame),
            }
            if writer is not None:
                line = format_candump(
                    stamp, args.channel, msg.arbitration_id, data, is_remote=msg.is_remote_frame, **flags
                )
                writer(line)
            yield from decoder.decode(msg.arbitration_id, data, msg.is_remote_frame, stamp, **flags)


def _proxy_records(args: argparse.Namespace, writer: Writer | None) -> Iterator[dict[str, Any]]:
    """A transparent TCP relay between clients and a gripper (or its gateway); both directions are decoded
    as they pass, by the family's byte stream dissector.

    Each client connection gets its own connection to the gripper and its own parsers, so two programs
    talking through the proxy do not garble each other's packets.
    """
    import selectors  # here, not at the top: `grippers --help` imports every command's module
    import socket

    from grippers.drivers.captures import format_hex_line
    from grippers.drivers.dissect import FROM_GRIPPER, TO_GRIPPER
    from grippers.drivers.inet import tcp_listener

    byte_stream(args)  # a protocol without a byte reader is refused before anything listens

    if args.to is None:
        raise UsageError("--proxy needs --to HOST:PORT (the gripper)")
    listener = tcp_listener(*args.proxy)
    host, port = listener.getsockname()[:2]
    print(
        f"grippers monitor: proxy listening on {host}:{port}, forwarding to {args.to[0]}:{args.to[1]}",
        file=sys.stderr,
        flush=True,
    )
    sel = selectors.DefaultSelector()
    listener.setblocking(False)
    sel.register(listener, selectors.EVENT_READ, None)
    end = None if args.duration is None else time.monotonic() + args.duration
    try:
        while end is None or time.monotonic() < end:
            wait = 0.25 if end is None else max(0.0, min(0.25, end - time.monotonic()))
            for key, _ in sel.select(wait):
                if key.data is None:
                    client, _addr = listener.accept()
                    try:
                        gripper = socket.create_connection(args.to, timeout=5.0)
                    except OSError as exc:
                        print(f"grippers monitor: cannot reach {args.to}: {exc}", file=sys.stderr)
                        client.close()
                        continue
                    stream = byte_stream(args)
                    for sock, peer, direction in (
                        (client, gripper, TO_GRIPPER),
                        (gripper, client, FROM_GRIPPER),
                    ):
                        sock.setblocking(False)
                        sel.register(sock, selectors.EVENT_READ, (peer, direction, stream))
                    continue
                ready = key.fileobj
                assert isinstance(ready, socket.socket)  # only sockets are registered
                sock = ready
                peer, direction, stream = key.data
                try:
                    data = sock.recv(65536)
                    if data:
                        peer.sendall(data)
                except OSError:
                    data = b""
                if not data:  # one side closed: close the pair
                    for s in (sock, peer):
                        try:
                            sel.unregister(s)
                        except (KeyError, ValueError):
                            pass
                        s.close()
                    continue
                stamp = time.time()
                if writer is not None:
                    writer(format_hex_line(stamp, direction, data))
                yield from stream.feed(direction, data, stamp)
    finally:
        for key in list(sel.get_map().values()):
            key.fileobj.close()  # type: ignore[union-attr]  # only file objects were registered
        sel.close()


Writer = Callable[[str], None]


def dissectors() -> dict[str, Any]:
    """Every installed family's ``dissector()`` (issue 28 §2), by family name and by protocol name."""
    from grippers.backends import available_backends, find_backend
    from grippers.backends.command_hooks import commands_of

    found: dict[str, Any] = {}
    for family in available_backends():
        try:
            dissector = commands_of(find_backend(family)).dissector()
        except Exception:  # a family whose optional dependency is missing dissects nothing here
            continue
        if dissector is not None:
            found.setdefault(family, dissector)
            found.setdefault(dissector.protocol, dissector)
    return found


def _chosen(args: argparse.Namespace) -> list[Any]:
    known = dissectors()
    if args.protocol == "auto":
        return list(dict.fromkeys(known.values()))
    if args.protocol not in known:
        raise UsageError(
            f"--protocol {args.protocol}: no such dissector (known: auto, {', '.join(sorted(known))})"
        )
    return [known[args.protocol]]


def can_decoder(args: argparse.Namespace) -> Any:
    """The CAN dissectors of the installed families (or the one ``--protocol`` names), one decoder."""
    from grippers.drivers.dissect import CanDecoder

    options = {"can_id": args.can_id, "only": args.protocol != "auto"}
    parts = [d.can(options) for d in _chosen(args) if d.can is not None]
    if not parts:
        raise UsageError(f"the {args.protocol} dissector reads no CAN frames")
    return CanDecoder(parts)


def byte_stream(args: argparse.Namespace) -> Any:
    """The byte stream dissector ``--protocol`` names (by default the one for unnamed byte captures)."""
    chosen = [d for d in _chosen(args) if d.stream is not None]
    if args.protocol == "auto":
        chosen = [d for d in chosen if d.bytes_default] or chosen
    if not chosen:
        raise UsageError(
            f"the {args.protocol} dissector reads CAN frames only: its captures are candump logs"
        )
    return chosen[0].stream()


class _Clock:
    """The time column as candump's ``-t``: absolute, relative to the first line, or delta to the last."""

    def __init__(self, kind: str) -> None:
        self.kind = kind
        self._first: float | None = None
        self._last: float | None = None

    def __call__(self, stamp: float | None) -> float | None:
        if stamp is None or self.kind == "a":
            return stamp
        if self._first is None:
            self._first = self._last = stamp
        shown = stamp - (self._first if self.kind in ("r", "z") else (self._last or stamp))
        self._last = stamp
        return shown


def apply_url(args: argparse.Namespace) -> None:
    """A connection URL in place of the capture FILE: the URLs every other command takes (issue 22 §2).

    ``can://IF/CH`` or ``FAMILY+can://IF/CH`` watch that bus (the family picks the decoder when
    ``--protocol`` is auto; ``?bitrate=`` as ``-b``, ``?send_id=`` as ``--can-id``);
    ``FAMILY+tcp://HOST[:PORT]`` relays through the proxy (``--proxy``, default a free loopback port) to that
    gripper, decoded by the family's byte stream dissector. Flags given beside the URL win over what the URL
    says, as they do for ``grippers.open``.
    """
    target = args.capture
    from grippers.urls import is_url

    if target is None or not is_url(target):
        return
    from grippers.drivers.urls import bus_options, scheme_of
    from grippers.errors import URLError
    from grippers.urls import parse_url, to_int

    bare = scheme_of(target) == "can"
    url = parse_url(target, bare_family="can" if bare else None)  # a bare bus: every family's frames
    dissector = dissectors().get(url.family) if not bare else None
    if url.transport == "can":
        args.interface = args.interface or url.interface
        args.channel = args.channel or url.channel
        if args.bitrate is None and "bitrate" in url.params:
            args.bitrate = to_int(url.params["bitrate"], "bitrate", target)
        if args.protocol == "auto" and dissector is not None and dissector.can is not None:
            args.protocol = url.family
        if "send_id" in url.params:
            args.can_id = can_id(url.params["send_id"])
        if "port" in url.params:  # a udp_multicast bus of its own (issue 33 §3: it watched the default port)
            args.bus_port = bus_options(url)["port"]
    elif url.transport == "tcp" and dissector is not None and dissector.stream is not None:
        if args.to is None:
            args.to = (url.host, url.port or dissector.tcp_port)
        if args.proxy is None:
            args.proxy = ("127.0.0.1", 0)
        if args.protocol == "auto":
            args.protocol = url.family
    else:
        raise URLError(
            "monitor watches a CAN bus (can://IF/CH, FAMILY+can://IF/CH) or a gripper over TCP through its "
            f"proxy (FAMILY+tcp://HOST[:PORT], for a family that dissects a byte stream), not {target}"
        )
    args.capture = None


def run(args: argparse.Namespace) -> int:
    from grippers.drivers.dissect import render_line

    apply_url(args)
    live_can = bool(args.interface or args.channel)
    sources = sum((args.capture is not None, live_can, args.proxy is not None))
    if sources == 0:
        raise UsageError(
            "give a capture FILE (or - for stdin), -i/--interface and -c/--channel for a live CAN bus, "
            "or --proxy HOST:PORT --to HOST:PORT for a TCP connection"
        )
    if sources > 1:
        raise UsageError("give one source: a capture FILE, -i/-c, or --proxy")
    if args.write and args.capture is not None:
        raise UsageError("--write saves live traffic (-i/-c or --proxy); a capture FILE is already saved")
    out = None
    if args.write:
        try:
            out = open(args.write, "w", encoding="ascii")  # noqa: SIM115 - closed in the finally below
        except OSError as exc:
            raise UsageError(f"cannot write {args.write}: {exc.strerror or exc}") from None

    def writer(line: str) -> None:
        assert out is not None
        out.write(line + "\n")
        out.flush()  # a capture cut by Ctrl-C keeps every line written so far

    try:
        if args.capture is not None:
            records = _capture_records(args)
        elif live_can:
            records = _live_can_records(args, writer if out else None)
        else:
            records = _proxy_records(args, writer if out else None)
        clock = _Clock(args.timestamps)
        decoded = 0
        for shown, rec in enumerate(records, start=1):
            rec["time"] = clock(rec["time"])
            if args.json:
                write_json({"schema": MONITOR_SCHEMA_ID, **rec})
            else:
                print(render_line(rec), flush=args.capture in (None, "-"))  # a pipe is shown as it comes
            decoded += rec["status"] != "noise"
            if args.count and shown >= args.count:
                break
    finally:
        if out is not None:
            out.close()
    if args.capture is not None and decoded == 0:
        print("grippers monitor: error: no complete packet or frame in the capture", file=sys.stderr)
        return EXIT_FAILED
    return EXIT_OK
