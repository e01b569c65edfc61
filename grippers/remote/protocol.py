"""The served key space and its JSON payloads, version 1 (docs/remote.md): pure code, no Zenoh, no I/O.

Kept apart from the server and the client so that both sides (and a program in another language reading
docs/remote.md) agree on one definition: the key of every resource, what each command takes, how a state
or an error looks on the wire. Parsing is strict: a payload that does not follow the table is refused with a
``ProtocolError`` before anything reaches a gripper.
"""

from __future__ import annotations

import json
import re
from dataclasses import dataclass, field
from typing import Any

from grippers.drivers.numbers import finite

from ..errors import CommandFailed, GripperError, ProtocolError

PROTOCOL_VERSION = 1
PREFIX = "grippers"
MAX_PAYLOAD = 64 * 1024  # bytes; a request is a few hundred, anything larger is refused unread
# Every Zenoh key expression below is built from chunks checked here, never from user text as given: a chunk
# is letters, digits, '.', '_' and '-' (not first), so no '/', '*', '$', '?' or '#' can change what the key
# means (extra chunks, wildcards, selectors) and no control character reaches a key or a log line (issue 43
# §3: a client id "cell/arm-1" declared a token the server never watched; "*" matched anyone's token).
_CHUNK = r"[A-Za-z0-9][A-Za-z0-9._-]"
NAME_RE = re.compile(_CHUNK + r"{0,63}")  # a served name (fullmatch: "$" would let a final newline in)
CLIENT_RE = re.compile(_CHUNK + r"{0,127}")  # a client id (ours: 32 hex digits)
MAX_LABEL = 256


def check_name(name: str) -> str:
    """A served name is one Zenoh key chunk: ``*``, ``$``, ``#``, ``?`` and ``/`` would change the key's
    meaning (wildcards, selectors, extra chunks)."""
    if not isinstance(name, str) or not NAME_RE.fullmatch(name):
        raise ValueError(
            f"served name {name!r}: letters, digits, '.', '_' and '-' only (1-64, not starting with . _ -)"
        )
    return name


def check_client(client: str) -> str:
    """A client id is one key chunk too (its liveliness token is ``grippers/NAME/client/ID``)."""
    if not isinstance(client, str) or not CLIENT_RE.fullmatch(client):
        raise ValueError(
            f"client id {client[:140]!r}: letters, digits, '.', '_' and '-' only (1-128, not starting "
            "with . _ -), one key chunk"
            if isinstance(client, str)
            else "client id must be a string"
        )
    return client


def check_label(label: str) -> str:
    """A label is shown to people (the server's log, another client's AccessDenied): printable text only,
    so it can forge no log line and put no terminal escape on anyone's screen."""
    if not isinstance(label, str) or len(label) > MAX_LABEL:
        raise ValueError(f"a label is a string of at most {MAX_LABEL} characters")
    if not label.isprintable():
        raise ValueError("a label is printable text: no control characters, no line breaks")
    return label


def token_key(name: str) -> str:
    """Liveliness token of a served gripper: present while it is served (presence and discovery)."""
    return f"{PREFIX}/{check_name(name)}"


def state_key(name: str) -> str:
    """States published at the server's rate and on every change; also a queryable (latest reading)."""
    return f"{token_key(name)}/state"


def info_key(name: str) -> str:
    return f"{token_key(name)}/info"


def command_key(name: str, command: str) -> str:
    if command not in COMMANDS:
        raise ValueError(f"unknown command {command!r}")
    return f"{token_key(name)}/cmd/{command}"


def client_key(name: str, client: str) -> str:
    """Liveliness token of a connected client: its deletion ends the lease it holds (the deadman's fast
    path); it never proves who sends a request (that is the lease secret: lease.py)."""
    return f"{token_key(name)}/client/{check_client(client)}"


def all_clients_key(name: str) -> str:
    return f"{token_key(name)}/client/*"


DISCOVERY_KEY = f"{PREFIX}/*"


# --- commands ---------------------------------------------------------------------------------------------

NUMBER, OPT_NUMBER, TEXT, ACTION = "number", "number?", "text", "action"


@dataclass(frozen=True)
class Command:
    """One command: its arguments (name -> kind) and how it meets the control lease.

    ``lease``: "take" (a motion: takes a free lease), "check" (changes the device: refused while another
    client holds the lease, does not take it), "free" (anyone, always: stop, fast_stop, reads).
    ``motion``: replies ``pending`` at once, then the final result when the motion ends.
    """

    args: dict[str, str] = field(default_factory=dict)
    lease: str = "free"
    motion: bool = False


def _from_table() -> dict[str, Command]:
    """The verbs of grippers/commands.py's table, with what each takes on the wire and its lease rule."""
    from .. import commands

    return {
        verb: Command(c.wire_args, c.served.lease, c.kind == commands.MOTION)
        for verb, c in commands.served().items()
        if c.served is not None
    }


COMMANDS: dict[str, Command] = {
    **_from_table(),
    # The lease itself: acquire (answers the secret), heartbeat and release (with it); never touches the
    # gripper, so it is the remote face's own verb and no Gripper command.
    "control": Command({"action": ACTION}),
}
CONTROL_ACTIONS = ("acquire", "heartbeat", "release")
SECRET_RE = re.compile(r"^[0-9a-f]{1,64}$")


@dataclass(frozen=True)
class Request:
    command: str
    client: str
    label: str
    args: dict[str, Any]
    lease: str | None = None  # the lease secret the request carries (lease.py), if any


def _number(value: Any, name: str, command: str) -> float:
    # A JSON number only (a string "1" is not one); finiteness, overflow (a 400-digit integer) and booleans
    # are the library's one rule (drivers/numbers.py), said as a ProtocolError: the request is malformed.
    if not isinstance(value, int | float):
        raise ProtocolError(
            f"argument {name!r} must be a number, not {type(value).__name__}", command=command
        )
    return finite(value, f"argument {name!r}", command=command, error=ProtocolError)


def decode_json(data: bytes, command: str) -> Any:
    if len(data) > MAX_PAYLOAD:
        raise ProtocolError(f"payload of {len(data)} bytes exceeds {MAX_PAYLOAD}", command=command)
    try:
        return json.loads(data.decode("utf-8"), parse_constant=_no_constant)
    except (UnicodeDecodeError, ValueError, RecursionError) as exc:
        raise ProtocolError(f"payload is not UTF-8 JSON: {exc}", command=command) from None


def _no_constant(name: str) -> Any:
    raise ValueError(f"{name} is not JSON")


def parse_request(command: str, data: bytes) -> Request:
    """A request payload checked against the command table; ProtocolError names what is wrong."""
    spec = COMMANDS.get(command)
    if spec is None:
        raise ProtocolError(f"unknown command {command!r}", command=command)
    if not data:
        # A query without a payload is never a command: it is what a Zenoh tool exploring the key space sends
        # (`z_get -s 'grippers/**'` reaches every queryable), and it must not stop or move anything.
        raise ProtocolError(
            'a command needs a request payload ({"v": 1, ...}); a query without one is never a command',
            command=command,
        )
    doc = decode_json(data, command)
    if not isinstance(doc, dict):
        raise ProtocolError(f"a request is a JSON object, not {type(doc).__name__}", command=command)
    unknown = set(doc) - {"v", "client", "label", "lease", "args"}
    if unknown:
        raise ProtocolError(f"unknown field(s) {', '.join(sorted(unknown))}", command=command)
    version = doc.get("v", PROTOCOL_VERSION)
    if version != PROTOCOL_VERSION:
        raise ProtocolError(
            f"protocol version {version!r}; this server speaks {PROTOCOL_VERSION}", command=command
        )
    client, label = doc.get("client", ""), doc.get("label", "")
    try:
        if client != "":  # free commands (stop, reads) may come from anyone, unnamed
            check_client(client)
        check_label(label)
    except ValueError as exc:
        raise ProtocolError(str(exc), command=command) from None
    lease = doc.get("lease")
    if lease is not None and not (isinstance(lease, str) and SECRET_RE.match(lease)):
        raise ProtocolError("lease must be the hexadecimal secret the server answered", command=command)
    raw = doc.get("args", {})
    if not isinstance(raw, dict):
        raise ProtocolError("args must be a JSON object", command=command)
    extra = set(raw) - set(spec.args)
    if extra:
        known = ", ".join(spec.args) or "none"
        raise ProtocolError(
            f"unknown argument(s) {', '.join(sorted(extra))} (takes: {known})", command=command
        )
    args: dict[str, Any] = {}
    for name, kind in spec.args.items():
        value = raw.get(name)
        if value is None:
            if kind in (NUMBER, TEXT, ACTION):
                raise ProtocolError(f"missing argument {name!r}", command=command)
            args[name] = None
        elif kind in (NUMBER, OPT_NUMBER):
            args[name] = _number(value, name, command)
        elif kind == TEXT:
            if not isinstance(value, str) or len(value) > 256:
                raise ProtocolError(f"argument {name!r} must be a string", command=command)
            args[name] = value
        else:
            if value not in CONTROL_ACTIONS:
                raise ProtocolError(f"action must be one of {', '.join(CONTROL_ACTIONS)}", command=command)
            args[name] = value
    if spec.lease != "free" and not client:
        raise ProtocolError("a command that needs the lease must name its client", command=command)
    if command == "control" and not client:
        raise ProtocolError("control must name its client", command=command)
    return Request(command, client, label, args, lease)


def encode_request(client: str, label: str, args: dict[str, Any], lease: str | None = None) -> bytes:
    doc: dict[str, Any] = {"v": PROTOCOL_VERSION, "client": client, "label": label, "args": args}
    if lease is not None:
        doc["lease"] = lease
    return dumps(doc)


def dumps(doc: Any) -> bytes:
    # allow_nan=False: NaN is not JSON, and a reader in another language would choke on it.
    return json.dumps(doc, separators=(",", ":"), allow_nan=False, default=str).encode()


# --- replies ----------------------------------------------------------------------------------------------

PENDING = "pending"
DONE = "done"


def encode_reply(status: str, result: Any = None, lease: str | None = None) -> bytes:
    """``lease``: the secret of a lease this very request took (the first reply of a motion, or the reply
    to ``control acquire``); only the querier receives a reply."""
    doc: dict[str, Any] = {"v": PROTOCOL_VERSION, "status": status, "result": result}
    if lease is not None:
        doc["lease"] = lease
    return dumps(doc)


def parse_reply(data: bytes, command: str) -> tuple[str, Any, str | None]:
    """(status, result, the lease secret if this reply grants one)."""
    doc = decode_json(data, command)
    if not isinstance(doc, dict) or doc.get("status") not in (PENDING, DONE):
        raise ProtocolError(
            f"reply is not a grippers/{PROTOCOL_VERSION} reply: {data[:200]!r}", command=command
        )
    lease = doc.get("lease")
    return doc["status"], doc.get("result"), lease if isinstance(lease, str) else None


# --- errors -----------------------------------------------------------------------------------------------


def encode_error(exc: BaseException, command: str) -> bytes:
    """An error as its class name, message and command; the client raises the same class again."""
    if isinstance(exc, GripperError):
        doc: dict[str, Any] = {
            "error": _wire_name(type(exc)),
            "message": exc.message,
            "command": exc.command or command,
            "device": exc.device,
        }
        for extra in ("status", "status_name", "holder", "width", "target"):  # MotionBlocked: width, target
            if getattr(exc, extra, None) is not None:
                doc[extra] = getattr(exc, extra)
    else:  # a bug on the server: said as such, never as a device error
        doc = {
            "error": "GripperError",
            "message": f"server error: {type(exc).__name__}: {exc}",
            "command": command,
        }
    doc["v"] = PROTOCOL_VERSION
    return dumps(doc)


def _wire_name(cls: type[GripperError]) -> str:
    """The name an error crosses the wire by: its own when clients know it, else its nearest ancestor's that
    they do (issue 43 §5: a served Robotiq's ``RobotiqFault``, a family's own CommandFailed, arrived as a
    plain GripperError "RobotiqFault: ..." without its status)."""
    known = error_classes()
    for ancestor in cls.__mro__:
        if known.get(ancestor.__name__) is ancestor:
            return ancestor.__name__
    return cls.__name__


def error_classes() -> dict[str, type[GripperError]]:
    """The exception classes that cross the wire by name; anything else arrives as a GripperError."""
    from .. import errors
    from ..gripper import FastStopActive

    table: dict[str, type[GripperError]] = {"FastStopActive": FastStopActive}
    for name in errors.__all__:
        cls = getattr(errors, name)
        if isinstance(cls, type) and issubclass(cls, GripperError):
            table[name] = cls
    return table


def is_query_timeout(data: bytes) -> bool:
    """Zenoh's own error reply when a query's timeout passes with no reply from a queryable (a server killed
    mid-query): no answer, not an answer we cannot read. Our servers' errors are JSON documents."""
    return data == b"Timeout"


def decode_error(data: bytes, command: str, device: str) -> GripperError:
    try:
        doc = decode_json(data, command)
    except ProtocolError:
        doc = None
    if not isinstance(doc, dict) or not isinstance(doc.get("error"), str):
        return ProtocolError(f"undecodable error reply: {data[:200]!r}", device=device, command=command)
    name, message = doc["error"], str(doc.get("message", ""))
    cmd = doc.get("command") if isinstance(doc.get("command"), str) else command
    cls = error_classes().get(name)
    if cls is None:
        return GripperError(f"{name}: {message}", device=device, command=cmd)
    kwargs: dict[str, Any] = {"device": device, "command": cmd}
    if issubclass(cls, CommandFailed):  # and its kinds (NotReferenced, MotionBlocked) keep the device's code
        kwargs["status"] = doc.get("status")
        kwargs["status_name"] = doc.get("status_name")
    if cls.__name__ == "MotionBlocked":
        for extra in ("width", "target"):
            value = doc.get(extra)
            kwargs[extra] = (
                float(value) if isinstance(value, int | float) and not isinstance(value, bool) else None
            )
    if cls.__name__ == "AccessDenied":
        kwargs["holder"] = doc.get("holder")
    try:
        return cls(message, **kwargs)
    except TypeError:  # a class with another constructor: keep the name and the message
        return GripperError(f"{name}: {message}", device=device, command=cmd)
