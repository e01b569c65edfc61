"""``grippers monitor``: decode live traffic or a capture into one readable line per frame or packet.

Sources: a capture file (candump log for CAN; hex dump or raw bytes for the WSG byte protocol; ``-`` reads
stdin, so ``candump -L can0 | grippers monitor -`` works), a live CAN bus (``-i``/``-c``), or a live WSG TCP
connection through ``--proxy``. The decoding is the drivers' own (the WSG packet parser and command table, the
STEPFOC frame table and their one-line descriptions), so the monitor shows exactly what the clients and
simulators understand, and there is no second copy of any byte layout here.
"""

from __future__ import annotations

import argparse
import itertools
import selectors
import socket
import sys
import time
from collections.abc import Callable, Iterator
from typing import IO, Any

from .common import add_can_flags, can_id, positive_float
from .output import EXIT_FAILED, EXIT_OK, MONITOR_SCHEMA_ID, UsageError, write_json

HELP = "decode live CAN traffic, a WSG TCP connection (--proxy) or a capture, one line per frame or packet"
EXAMPLE = (
    "grippers monitor capture.log            (candump -L format)\n"
    "         grippers monitor wsg.hex --protocol wsg\n"
    "         grippers monitor -i socketcan -c can0 --protocol stepfoc\n"
    "         grippers monitor stepfoc+can://socketcan/can0      (the URL the other commands take)\n"
    "         grippers monitor wsg+tcp://192.168.1.20            (through a proxy on a free port)\n"
    "         grippers monitor --proxy 127.0.0.1:1000 --to 192.168.1.20:1000\n"
    "         candump -L can0 | grippers monitor -\n"
    "         grippers monitor -i socketcan -c can0 -t r --write session.log   (record a fixture)"
)

PROTOCOLS = ("auto", "wsg", "stepfoc")
FORMATS = ("auto", "candump", "hex", "raw")
# The longest line a text capture may have: a --proxy --write line holds one 64 KiB read, 128 KiB of hex. A
# longer one is not a capture (``monitor /dev/zero`` read 7.9 GB looking for the first line end, issue 33 §3).
MAX_LINE = 1 << 20
CHUNK = 1 << 16  # a raw capture is decoded in pieces of this size, as they arrive


def _host_port(text: str) -> tuple[str, int]:
    host, sep, port = text.rpartition(":")
    try:
        number = int(port)
    except ValueError:
        number = -1
    if not sep or not host or not 0 <= number <= 65535:
        raise argparse.ArgumentTypeError(f"expected HOST:PORT, not {text!r}")
    return host.strip("[]"), number


def add_arguments(parser: argparse.ArgumentParser) -> None:
    parser.add_argument(
        "capture",
        nargs="?",
        metavar="FILE|URL",
        help="capture file, or - for stdin; or a URL: can://IF/CH, stepfoc+can://IF/CH, wsg+can://IF/CH "
        "(a live bus, like -i/-c), wsg+tcp://HOST[:PORT] (through the proxy); omit with -i/-c or --proxy",
    )
    parser.add_argument("--format", choices=FORMATS, default="auto", help="capture format (default: detect)")
    parser.add_argument(
        "--protocol",
        choices=PROTOCOLS,
        default="auto",
        help="decode CAN frames as WSG or STEPFOC (default: frames on the WSG ids that carry a WSG packet "
        "as WSG, the rest as STEPFOC); byte captures are always WSG",
    )
    parser.add_argument(
        "--wsg-id",
        type=can_id,
        default=0x000,
        metavar="ID",
        help="WSG over CAN: the command id; replies come on ID+1 (default 0x000, docs/protocols.md §1)",
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
        help="live WSG over TCP: listen here (port 0: a free port, printed on stderr), forward to --to",
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
            "(raw WSG bytes: --format raw)"
        )

    def sniff(self) -> str:
        """'candump', 'hex' or 'raw' from the first significant line, as :func:`sniff_format` decides."""
        from grippers.drivers.captures import looks_like_text, sniff_format
        from grippers.drivers.wsg.protocol import PREAMBLE

        held = 0
        while held <= MAX_LINE:  # blank lines and comments before the first record: bounded too
            line = self._readline()
            self._head.append(line)
            held += len(line)
            if not line:
                break
            if not looks_like_text(line):
                if len(line) > MAX_LINE and PREAMBLE not in line:
                    raise UsageError(
                        f"{self.name}: not a capture: no line end in the first {MAX_LINE} bytes, and no WSG "
                        "packet in them (raw WSG bytes anyway: --format raw)"
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


def _capture_records(args: argparse.Namespace) -> Iterator[dict[str, Any]]:
    from grippers.drivers.captures import (
        FROM_DEVICE,
        TO_DEVICE,
        UNKNOWN_DIRECTION,
        CaptureError,
        parse_candump,
        parse_hex_dump,
    )
    from grippers.drivers.dissect import CanDecoder
    from grippers.drivers.wsg.dissect import WsgStream

    capture = _Capture(args.capture)
    try:
        fmt = args.format if args.format != "auto" else capture.sniff()
        if fmt == "candump":
            decoder = CanDecoder(args.protocol, args.wsg_id)
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
        if args.protocol == "stepfoc":
            raise UsageError("a byte capture holds WSG packets; STEPFOC captures are candump logs")
        default = {"to": TO_DEVICE, "from": FROM_DEVICE}.get(args.direction, UNKNOWN_DIRECTION)
        stream = WsgStream()
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
    from grippers.drivers.dissect import CanDecoder

    if not (args.interface and args.channel):
        raise UsageError(
            "live monitoring needs both -i/--interface and -c/--channel (or give a capture FILE)"
        )
    kwargs: dict[str, Any] = {"interface": args.interface, "channel": args.channel}
    if args.bitrate:
        kwargs["bitrate"] = args.bitrate
    decoder = CanDecoder(args.protocol, args.wsg_id)
    end = None if args.duration is None else time.monotonic() + args.duration
    with can.Bus(**kwargs) as bus:
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
    """A transparent TCP relay between clients and a WSG; both directions are decoded as they pass.

    Each client connection gets its own connection to the gripper and its own parsers, so two programs
    talking through the proxy do not garble each other's packets.
    """
    from grippers.drivers.captures import format_hex_line
    from grippers.drivers.dissect import FROM_GRIPPER, TO_GRIPPER
    from grippers.drivers.wsg.dissect import WsgStream

    if args.to is None:
        raise UsageError("--proxy needs --to HOST:PORT (the gripper)")
    listener = socket.create_server(args.proxy)
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
                    stream = WsgStream()
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

    ``can://IF/CH`` and ``stepfoc+can://IF/CH`` or ``wsg+can://IF/CH[?send_id=ID]`` watch that bus (the family
    picks the decoder when ``--protocol`` is auto; ``?bitrate=`` as ``-b``); ``wsg+tcp://HOST[:PORT]`` relays
    through the proxy (``--proxy``, default a free loopback port) to that gripper. Flags given beside the URL
    win over what the URL says, as they do for ``grippers.open``.
    """
    target = args.capture
    if target is None or "://" not in target:
        return
    from grippers.errors import URLError
    from grippers.profiles import WsgTransport
    from grippers.urls import parse_url

    bare = target.lower().startswith("can://")
    url = parse_url(("stepfoc+" + target) if bare else target)
    if url.transport == "can":
        args.interface = args.interface or url.interface
        args.channel = args.channel or url.channel
        if args.bitrate is None and "bitrate" in url.params:
            args.bitrate = int(url.params["bitrate"], 0)
        if args.protocol == "auto" and not bare:
            args.protocol = url.family
        if url.family == "wsg" and "send_id" in url.params:
            args.wsg_id = can_id(url.params["send_id"])
    elif url.family == "wsg" and url.transport == "tcp":
        if args.to is None:
            args.to = (url.host, url.port or WsgTransport().tcp_port)
        if args.proxy is None:
            args.proxy = ("127.0.0.1", 0)
    else:
        raise URLError(
            "monitor watches a CAN bus (can://IF/CH, stepfoc+can://, wsg+can://) or a WSG over TCP through "
            f"its proxy (wsg+tcp://HOST[:PORT]), not {target}"
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
            "or --proxy HOST:PORT --to HOST:PORT for a WSG TCP connection"
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
