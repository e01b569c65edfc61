"""``grippers probe [URL]``: find out what answers at a URL, a bare transport, the simulators or this machine.

Every candidate is tried in its own daemon thread with a hard deadline, so a silent port, a device that
sends garbage or a driver that blocks cannot stretch the probe beyond its bound: what has not answered by
then is reported as silent and abandoned. Candidates that share a resource (one serial port) run one after
another; the others run in parallel.
"""

from __future__ import annotations

import argparse
import sys
import threading
import time
from dataclasses import dataclass
from typing import Any

from .common import DEFAULT_TIMEOUT, add_can_flags, can_id, positive_float
from .output import (
    EXIT_FAILED,
    EXIT_OK,
    PROBE_SCHEMA_ID,
    Progress,
    UsageError,
    fmt_num,
    info_dict,
    state_dict,
    table,
    write_json,
)

HELP = "identify the grippers at a URL, a bare transport (tcp://, serial://, can://), sim:// or this machine"
EXAMPLE = (
    "grippers probe sim://\n"
    "         grippers probe tcp://127.0.0.1:1000 --json\n"
    "         grippers probe can://socketcan/can0 --timeout 0.5\n"
    "         grippers probe -i udp_multicast -c 239.74.163.2 --can-id 0x7E8\n"
    "         grippers probe            (this machine: serial ports, SocketCAN, factory addresses)"
)

# Per-candidate hard deadline, in multiples of --timeout: opening (one exchange) plus info and state reads.
DEADLINE_FACTOR = 3.0
DEADLINE_SLACK = 0.5  # seconds, for thread start-up and imports


def add_arguments(parser: argparse.ArgumentParser) -> None:
    parser.add_argument(
        "target",
        metavar="URL",
        nargs="?",
        help="tcp://HOST[:PORT], udp://HOST[:PORT], serial://PORT, can://INTERFACE/CHANNEL, a family URL "
        "(FAMILY+tcp://..., FAMILY+can://...), sim:// (all simulators) or sim://PROFILE; "
        "none: scan this machine",
    )
    parser.add_argument(
        "-t",
        "--timeout",
        type=positive_float,
        default=DEFAULT_TIMEOUT,
        metavar="SECONDS",
        help=f"time each device gets to answer (default {DEFAULT_TIMEOUT:g})",
    )
    parser.add_argument("--json", action="store_true", help="print one JSON document (schema in docs/cli.md)")
    parser.add_argument(
        "--no-network",
        dest="network",
        action="store_false",
        help="with no URL, leave out the families' factory network addresses (no traffic on the LAN)",
    )
    parser.add_argument(
        "--can-id",
        type=can_id,
        action="append",
        metavar="ID",
        help="on a bare CAN bus, for a family that takes commands on a CAN id and replies on the next: "
        "look on ID and ID+1 (repeatable; default: the ids of the family's profiles)",
    )
    parser.add_argument(
        "--profile",
        metavar="NAME",
        help="device profile for the candidates of its family (for a device that cannot report its model "
        "or stroke)",
    )
    add_can_flags(parser)


IDENTITY = ("family", "vendor", "model", "profile", "firmware", "hardware", "serial")


@dataclass
class Outcome:
    kind: str  # "gripper", "other" (answered, not a gripper), "silent" (no answer, error)
    url: str
    location: dict[str, Any]
    device: dict[str, Any] | None = None
    reason: str | None = None
    identity: dict[str, Any] | None = None  # the family's probe_identity verdict (probe_identity.py)


def probe_one(url: str, location: dict[str, Any], timeout: float, profile: Any = None) -> Outcome:
    """Open one family URL and read what it is and its state; classify any failure. ``profile`` (a loaded
    profile) is used for the URLs of its own family only."""
    import grippers

    kwargs: dict[str, Any] = {"timeout": timeout}
    if profile is not None and url.lower().startswith(f"{profile.family}+"):
        kwargs["profile"] = profile
    try:
        gripper = grippers.open(url, **kwargs)
    except Exception as exc:
        outcome = _failed(url, location, exc)
        if outcome.kind == "silent" and isinstance(exc, TimeoutError):
            noise = garbage_check(url, timeout)
            if noise:  # bytes came back, none of them an answer: a device, but not one we understand
                return Outcome("other", url, location, reason=noise)
        return outcome
    try:
        info = info_dict(gripper.info())
        try:
            state: dict[str, Any] | None = state_dict(gripper.state())
        except Exception as exc:  # identified, but the state read failed: still a gripper
            state = {"error": _failed(url, location, exc).reason or ""}
        device = {
            "url": url,
            **{k: info[k] for k in IDENTITY},
            "location": location,
            "state": state,
            "limits": info["limits"],
            "warnings": [str(w) for w in (info.get("extra") or {}).get("warnings", [])],
        }
        from .probe_identity import identity_of

        return Outcome("gripper", url, location, device=device, identity=identity_of(url, gripper))
    except Exception as exc:
        return _failed(url, location, exc)
    finally:
        try:
            gripper.close()
        except Exception:
            pass


def _failed(url: str, location: dict[str, Any], exc: Exception) -> Outcome:
    """Silence and transport failures are 'silent'; an answer that is not a gripper's is 'other'; a usage
    error or a bug in our own code propagates (the probe must not hide it behind 'no answer')."""
    from grippers.errors import GripperError, ProfileError, URLError

    if isinstance(exc, URLError | ProfileError):
        raise exc
    if isinstance(exc, TimeoutError | OSError):  # GripperTimeout, ConnectionLost, refused, no such port
        return Outcome("silent", url, location, reason=_reason(exc))
    if isinstance(exc, GripperError):  # ProtocolError, CommandFailed, NotSupported: it answered, oddly
        return Outcome("other", url, location, reason=_reason(exc))
    raise exc


def garbage_check(url: str, timeout: float) -> str | None:
    """After a timeout on a byte stream (TCP, UDP, serial): ask once more on a raw connection and count what
    comes back. A device that answers with bytes that are not a packet of the family is reported as sending
    garbage (wrong baud rate, wrong protocol), not as silent. None when nothing came back, or when the family
    offers no raw probe (its backend's ``raw_probe`` hook)."""
    from grippers.backends import find_backend
    from grippers.backends.command_hooks import commands_of
    from grippers.errors import URLError
    from grippers.urls import parse_url, to_int

    try:
        u = parse_url(url)
    except URLError:
        return None  # opening it has said why
    family, transport = u.family, u.transport
    raw = commands_of(find_backend(family)).raw_probe(transport)
    if raw is None:
        return None
    request, goodbye = raw.request, raw.goodbye
    received = b""
    try:
        if transport in ("tcp", "udp"):
            import socket

            from grippers.drivers.inet import family_of

            kind = socket.SOCK_STREAM if transport == "tcp" else socket.SOCK_DGRAM
            with socket.socket(family_of(u.host), kind) as s:
                s.settimeout(timeout)
                s.connect((u.host, u.port or raw.port))
                s.sendall(request)
                end = time.monotonic() + timeout
                while time.monotonic() < end and len(received) < 64:
                    s.settimeout(max(0.01, end - time.monotonic()))
                    try:
                        chunk = s.recv(256)
                    except TimeoutError:
                        break
                    if not chunk:
                        break
                    received += chunk
                if goodbye:
                    try:
                        s.sendall(goodbye)
                    except OSError:
                        pass
        elif transport == "serial":
            import serial

            baud = to_int(u.params.get("baudrate", 115200), "baudrate", url)
            with serial.Serial(u.serial_port, baud, timeout=timeout, write_timeout=timeout) as ser:
                ser.reset_input_buffer()
                ser.write(request)
                received = ser.read(64)
        else:
            return None
    except (OSError, ValueError, ImportError):
        return None
    if not received or (raw.is_answer is not None and raw.is_answer(received)):
        return None  # silent, or a real device of the family that answered late: the timeout stands
    return (
        f"sends bytes that are not a {family} answer ({len(received)}+ bytes, starting "
        f"{received[:8].hex(' ')}): a different protocol or baud rate?"
    )


def _reason(exc: BaseException) -> str:
    text = " ".join(str(exc).split()) or type(exc).__name__
    return f"{type(exc).__name__}: {text}"


def _load_backends() -> None:
    """Import the backends and read the profiles before any candidate's deadline starts.

    A candidate's bound is the protocol's (``DEADLINE_FACTOR`` timeouts); the first ``open()`` in a process
    also imports the backends and parses every profile, which takes a second on a loaded machine and would
    otherwise count against the first candidates as silence.
    """
    from grippers.profiles import list_profiles

    from .probe_targets import _backends

    _backends()
    list_profiles()


class _Runner:
    """Runs candidate groups in parallel daemon threads, each candidate under a hard deadline."""

    def __init__(self, timeout: float, progress: Progress, profile: Any = None) -> None:
        _load_backends()
        self.profile = profile
        self.timeout = timeout
        self.progress = progress
        self.outcomes: dict[str, Outcome] = {}
        self._lock = threading.Lock()

    def _attempt(self, candidate: Any) -> Outcome:
        box: list[Outcome] = []
        errors: list[BaseException] = []

        def work() -> None:
            try:
                box.append(probe_one(candidate.url, candidate.location, self.timeout, self.profile))
            except BaseException as exc:  # re-raised in the caller's thread
                errors.append(exc)

        worker = threading.Thread(target=work, name=f"probe {candidate.url}", daemon=True)
        worker.start()
        worker.join(self.timeout * DEADLINE_FACTOR + DEADLINE_SLACK)
        if errors:
            raise errors[0]
        if box:
            return box[0]
        return Outcome(
            "silent",
            candidate.url,
            candidate.location,
            reason=f"no complete answer within {self.timeout * DEADLINE_FACTOR:g} s; abandoned",
        )

    def run_groups(self, candidates: list[Any]) -> list[BaseException]:
        groups: dict[str, list[Any]] = {}
        for c in candidates:
            groups.setdefault(c.group, []).append(c)
        failures: list[BaseException] = []

        def run_group(items: list[Any]) -> None:
            answered: str | None = None  # the protocol that answered here: its other families are tried too
            for c in items:
                if answered is not None and c.protocol != answered:
                    continue
                self.progress.update(f"probing {c.url} ...")
                try:
                    outcome = self._attempt(c)
                except BaseException as exc:
                    failures.append(exc)
                    return
                with self._lock:
                    self.outcomes[c.url] = outcome
                if outcome.kind == "gripper":
                    if c.protocol is None:
                        return  # one protocol answered on this resource: the others cannot share it
                    answered = c.protocol

        threads = [
            threading.Thread(target=run_group, args=(items,), daemon=True) for items in groups.values()
        ]
        for t in threads:
            t.start()
        bound = max((len(items) for items in groups.values()), default=0)
        deadline = time.monotonic() + bound * (self.timeout * DEADLINE_FACTOR + DEADLINE_SLACK) + 1.0
        for t in threads:
            t.join(max(0.0, deadline - time.monotonic()))
        return failures


def _sim_targets() -> list[str]:
    """sim://PROFILE for every profile on the search path whose backend has a simulator."""
    from grippers.backends import find_backend
    from grippers.profiles import list_profiles

    names = []
    for profile in list_profiles():
        backend = find_backend(profile.family)
        if backend is not None and hasattr(backend, "simulator"):
            names.append(profile.name)
    return [f"sim://{name}" for name in sorted(names)]


def collect(
    target: str | None,
    timeout: float,
    network: bool,
    bitrate: int | None,
    progress: Progress,
    can_ids: list[int] | None = None,
    profile: str | None = None,
) -> dict[str, Any]:
    """Probe and build the JSON document (grippers.probe/2)."""
    from grippers.urls import scheme_of

    from . import probe_targets as pt

    loaded = None
    if profile is not None:
        from grippers.profiles import load_profile

        loaded = load_profile(profile)  # an unknown name is a usage error before anything is sent

    if target is None:
        plan = pt.machine_targets(network=network, bitrate=bitrate, options={"can_ids": can_ids})
    elif scheme_of(target) == "zenoh":  # grippers served over Zenoh: ask who is served (docs/remote.md)
        from grippers.remote import served_urls

        plan = pt.Plan([pt.Candidate(u, pt.location_of(u), group=u) for u in served_urls(target, timeout)])
    else:
        plan = pt.expand(target, bitrate=bitrate, options={"can_ids": can_ids})
        if plan.sim_all:
            for url in _sim_targets():
                plan.candidates.append(pt.Candidate(url, pt.location_of(url), group=url))
    first = [c for c in plan.candidates if not c.unless_nodes]
    later = [c for c in plan.candidates if c.unless_nodes]
    runner = _Runner(timeout, progress, loaded)
    failures = runner.run_groups(first)
    skipped = list(plan.skipped)
    if later:
        runnable = []
        for c in later:
            busy = [
                o
                for o in runner.outcomes.values()
                if o.kind != "silent"
                and o.location.get("node") in c.unless_nodes
                and o.location.get("interface") == c.location.get("interface")
                and o.location.get("channel") == c.location.get("channel")
            ]
            if busy:
                skipped.append(
                    {
                        "target": c.url,
                        "reason": "a device answers at the bus node these CAN ids address; this "
                        "probe's frame would reach it as a command there; not sent",
                    }
                )
            else:
                runnable.append(c)
        failures += runner.run_groups(runnable)
    progress.done()
    if failures:
        raise failures[0]
    order = {c.url: i for i, c in enumerate(plan.candidates)}
    outcomes = sorted(runner.outcomes.values(), key=lambda o: order.get(o.url, 0))
    from .probe_identity import resolve

    outcomes = resolve(outcomes, {c.url: c.group for c in plan.candidates})
    return {
        "schema": PROBE_SCHEMA_ID,
        "target": target,
        "timeout_s": timeout,
        "grippers": [o.device for o in outcomes if o.kind == "gripper"],
        "others": [
            {"url": o.url, "location": o.location, "reason": o.reason} for o in outcomes if o.kind == "other"
        ],
        "silent": [
            {"url": o.url, "location": o.location, "reason": o.reason} for o in outcomes if o.kind == "silent"
        ],
        "skipped": skipped,
    }


def where(location: dict[str, Any]) -> str:
    t = location.get("transport")
    if t in ("tcp", "udp"):
        port = location.get("port")
        return f"{t} {location.get('host')}" + ("" if port is None else f":{port}")
    if t == "serial":
        return f"serial {location.get('serial_port')}"
    if t == "can":
        node = location.get("node")
        return f"can {location.get('interface')}/{location.get('channel')}" + (
            f" node {node}" if node is not None else ""
        )
    if location.get("profile"):
        return f"sim {location['profile']}"
    return str(t or "-")


def _cause(reason: str | None, url: str) -> str:
    """A failure's reason without the device it names, so that the same cause at sixteen CAN nodes is one
    line: 'ConnectionLost: stepfoc+can://socketcan/can9: open: cannot open the CAN bus: ...' ->
    'ConnectionLost: cannot open the CAN bus: ...'."""
    if not reason:
        return "-"
    from grippers.urls import is_url

    kind, sep, text = reason.partition(": ")
    if not sep:
        return reason
    segments = text.split(": ")
    while len(segments) > 1 and (
        is_url(segments[0])
        or segments[0].startswith(("serial:", "/"))
        or segments[0] in url
        or segments[0].isidentifier()
    ):
        segments.pop(0)
    return f"{kind}: {': '.join(segments)}"


def _key(cause: str) -> str:
    """What makes two failures the same: the operating system's error when there is one (the WSG and the
    STEPFOC drivers word 'cannot open the CAN bus' differently around the same [Errno 19])."""
    kind, _, text = cause.partition(": ")
    errno = text.find("[Errno ")
    return f"{kind}: {text[errno:]}" if errno >= 0 else cause


def collapse(misses: list[dict[str, Any]]) -> list[tuple[list[str], str]]:
    """Misses grouped by their cause, in first-seen order: one line per distinct failure."""
    groups: dict[str, list[str]] = {}
    shown: dict[str, str] = {}
    reasons: dict[str, str] = {}
    for miss in misses:
        cause = _cause(miss.get("reason"), miss["url"])
        key = _key(cause)
        groups.setdefault(key, []).append(miss["url"])
        shown.setdefault(key, cause)
        reasons.setdefault(key, miss.get("reason") or "-")
    return [(urls, shown[key] if len(urls) > 1 else reasons[key]) for key, urls in groups.items()]


def _urls(urls: list[str]) -> str:
    return urls[0] if len(urls) == 1 else f"{urls[0]} and {len(urls) - 1} more"


def render(doc: dict[str, Any]) -> str:
    lines: list[str] = []
    rows = []
    for d in doc["grippers"]:
        s = d.get("state") or {}
        lim = d.get("limits") or {}
        faults = s.get("faults")
        rows.append(
            [
                d.get("vendor"),
                d.get("model"),
                d.get("firmware"),
                d.get("serial"),
                where(d["location"]),
                fmt_num(s.get("width_mm"), "mm", 1),
                s.get("grasp_state") or s.get("error"),
                None if s.get("referenced") is None else ("yes" if s["referenced"] else "no"),
                ", ".join(faults) if faults else ("none" if faults is not None else None),
                f"{fmt_num(lim.get('min_width_mm'), '', 0)}-{fmt_num(lim.get('max_width_mm'), 'mm', 0)}",
                fmt_num(lim.get("max_force_n"), "N", 0),
            ]
        )
    if rows:
        headers = [
            "VENDOR",
            "MODEL",
            "FIRMWARE",
            "SERIAL",
            "WHERE",
            "WIDTH",
            "GRASP",
            "REFERENCED",
            "FAULTS",
            "STROKE",
            "FORCE",
        ]
        lines.append(table(rows, headers))
        lines.append("")
        lines.append(f"{len(rows)} gripper(s) found; the other commands open them with these URLs:")
        lines += [f"  {d['url']}" for d in doc["grippers"]]
    else:
        lines.append("no gripper found")
    for d in doc["grippers"]:
        for warning in d.get("warnings") or []:
            lines.append(f"warning: {d['url']}: {warning}")
        shared = d.get("same_port")
        if shared and shared["kept"][0] == d["url"]:
            lines.append(f"{where(d['location'])}: {', '.join(shared['answered'])} answered; {shared['why']}")
    for urls, reason in collapse(doc["others"]):
        lines.append(f"answered, not a gripper: {_urls(urls)} ({reason})")
    silent = collapse(doc["silent"])
    if not rows or len(silent) <= 4:
        for urls, reason in silent:
            lines.append(f"no answer: {_urls(urls)} ({reason})")
    else:
        lines.append(f"no answer at {len(doc['silent'])} other address(es); --json lists them")
    for s in doc["skipped"]:
        lines.append(f"skipped: {s['target']} ({s['reason']})")
    return "\n".join(lines)


def run(args: argparse.Namespace) -> int:
    if args.interface or args.channel:
        if args.target is not None:
            raise UsageError("give either a URL or -i/-c, not both")
        if not (args.interface and args.channel):
            raise UsageError("-i/--interface and -c/--channel go together")
        args.target = f"can://{args.interface}/{args.channel}"
    progress = Progress()
    doc = collect(args.target, args.timeout, args.network, args.bitrate, progress, args.can_id, args.profile)
    if args.json:
        write_json(doc)
    else:
        print(render(doc))
        sys.stdout.flush()
    return EXIT_OK if doc["grippers"] else EXIT_FAILED
