"""Every public command of a :class:`~grippers.Gripper`, declared once (issue 32 §3).

Why a table: a command used to be written five times (the threaded gripper, the asyncio face, the remote
protocol's command table, the server's dispatch and the remote client's stubs, the CLI), and copies drift.
Here each one is described once: its parameters with their units and defaults, its kind, how the asyncio
face offers it, whether ``grippers serve`` serves it and under which remote verb, and which CLI subcommand
calls it. From this table:

- ``grippers.remote.protocol.COMMANDS`` (what each verb takes on the wire, its lease rule) is derived;
- the server's dispatch calls the Gripper method the verb names, with the arguments the table lists;
- the remote client sends exactly the arguments the table lists (``grippers.remote.link.ServedLink.command``);
- the asyncio face's forwarding methods take the Gripper method's own signature and lane.

tests/test_command_table.py checks the rest against it: every public Gripper method is here with the
parameters it really has, every one has an asyncio twin with the same parameters, the remote client sends
what the table says is served, the CLI's motion commands (and their options) match the table's motions and
``cli`` entries, and docs/remote.md's verb table says what this one says.

Adding a command: declare it here, write the Gripper method (and the backend hook it needs), add its
asyncio twin (one line when it forwards); the remote protocol, server and CLI checks follow.

Pure data, no imports from the rest of the library. The CLI does not import it (``grippers --help`` stays
fast); its motion list is checked against it instead.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

__all__ = [
    "COMMANDS",
    "CONTROL",
    "FACE_HOOKS",
    "MOTION",
    "QUERY",
    "REQUIRED",
    "STREAM",
    "Command",
    "Param",
    "Served",
    "motions",
    "served",
]

# Kinds of command.
MOTION = "motion"  # moves the jaws and ends when they stop; a handle with wait=False; takes the remote lease
CONTROL = "control"  # changes the device or the session (stop, acknowledge, settings, close); no handle
QUERY = "query"  # reads, or checks without sending anything; changes nothing
STREAM = "stream"  # goes on after it returns: states out (stream, on_connection) or targets in (servo)

# How the asyncio twin (grippers/aio.py) is called.
AWAIT = "await"  # ``await g.name(...)``: a coroutine
ITERATE = "iterate"  # ``async for st in g.name(...)``: an async generator
PLAIN = "plain"  # ``g.name(...)``: nothing waits on the device (a local check, a callback registration)

# How a served command crosses the remote protocol (docs/remote.md).
VERB = "verb"  # a query on grippers/<name>/cmd/<verb> with the arguments below
KEY = "key"  # a query on grippers/<name>/<verb> (state, info): no arguments, never a lease
SUBSCRIPTION = "subscription"  # a subscription to grippers/<name>/<verb> (the published states)

# Parameter types and their wire kinds (grippers/remote/protocol.py).
NUMBER, TEXT, OTHER = "number", "text", "other"


class _Required:
    def __repr__(self) -> str:
        return "REQUIRED"


REQUIRED: Any = _Required()
"""The default of a parameter that has none."""


@dataclass(frozen=True)
class Param:
    """One parameter: its name, type, unit (SI; "" for none), default and whether it is keyword-only.

    ``sent``: whether a served command carries it over the wire (``wait`` never does: the server waits,
    the client's handle does the rest)."""

    name: str
    type: str = NUMBER
    unit: str = ""
    default: Any = REQUIRED
    keyword_only: bool = False
    sent: bool = True

    @property
    def required(self) -> bool:
        return self.default is REQUIRED

    @property
    def wire(self) -> str:
        """Its kind in the remote protocol's command table: "number", "number?" or "text"."""
        if self.type == TEXT:
            return "text"
        if self.type == NUMBER:
            return "number" if self.required else "number?"
        raise ValueError(f"parameter {self.name!r} of type {self.type!r} cannot cross the wire")


@dataclass(frozen=True)
class Served:
    """How ``grippers serve`` offers a command: ``how`` is VERB, KEY or SUBSCRIPTION, ``verb`` its name
    on the key space, ``lease`` the control-lease rule of a VERB: "take" (a motion or servoing takes a free
    lease), "check" (changes the device: refused while another client holds it), "free" (anyone, always)."""

    verb: str
    how: str = VERB
    lease: str = "free"


@dataclass(frozen=True)
class Command:
    """One public Gripper method.

    ``urgent``: run on the faces' own lane (the server's urgent pool, the asyncio face's control worker),
    never queued behind reads or settings: what ends or clears a motion must reach the device at once.
    ``aio_omits``: parameters the asyncio twin leaves out on purpose, with the reason in the summary.
    ``cli``: the ``grippers`` subcommands (with their flag) that call it.
    """

    name: str
    kind: str
    summary: str
    params: tuple[Param, ...] = ()
    aio: str = AWAIT
    served: Served | None = None
    urgent: bool = False
    aio_omits: tuple[str, ...] = ()
    cli: tuple[str, ...] = ()

    def param(self, name: str) -> Param:
        return next(p for p in self.params if p.name == name)

    @property
    def wire_args(self) -> dict[str, str]:
        """What a served VERB takes on the wire: argument name -> "number", "number?" or "text"."""
        return {p.name: p.wire for p in self.params if p.sent}


def _width(default: Any = REQUIRED, name: str = "width") -> Param:
    return Param(name, NUMBER, "m", default)


_SPEED = Param("speed", NUMBER, "m/s", None)
_FORCE = Param("force", NUMBER, "N", None)
_WAIT = Param("wait", OTHER, "", True, keyword_only=True, sent=False)
_TIMEOUT = Param("timeout", NUMBER, "s", None, keyword_only=True)
_TAKE, _CHECK = "take", "check"

_TABLE = (
    # -- motions: one at a time, the newest wins (grippers/motions.py) ---------------------------------------
    Command(
        "home",
        MOTION,
        "reference the axis: homing, calibration or activation, as the family does",
        (Param("timeout", NUMBER, "s", None), _WAIT),
        served=Served("home", lease=_TAKE),
        cli=("home",),
    ),
    Command(
        "move",
        MOTION,
        "move the fingers to a width without gripping",
        (_width(), _SPEED, _WAIT, _TIMEOUT),
        served=Served("move", lease=_TAKE),
        cli=("move",),
    ),
    Command(
        "grasp",
        MOTION,
        "close on a part of a nominal width with a force",
        (_width(), _SPEED, _FORCE, _WAIT, _TIMEOUT),
        served=Served("grasp", lease=_TAKE),
        cli=("grasp",),
    ),
    Command(
        "release",
        MOTION,
        "open to a width (default fully open), ending a grasp",
        (_width(None), _SPEED, _WAIT, _TIMEOUT),
        served=Served("release", lease=_TAKE),
        cli=("release",),
    ),
    # -- control ---------------------------------------------------------------------------------------------
    Command(
        "stop", CONTROL, "stop the fingers where they are", served=Served("stop"), urgent=True, cli=("stop",)
    ),
    Command(
        "fast_stop",
        CONTROL,
        "stop at once; motion is refused until acknowledge()",
        served=Served("fast_stop"),
        urgent=True,
        cli=("stop --fast",),
    ),
    Command(
        "acknowledge",
        CONTROL,
        "clear a fast stop",
        served=Served("acknowledge", lease=_CHECK),
        urgent=True,
        cli=("ack",),
    ),
    Command(
        "set_soft_limits",
        CONTROL,
        "limits the device itself enforces on finger motion",
        (_width(name="min_width"), _width(name="max_width")),
        served=Served("set_soft_limits", lease=_CHECK),
    ),
    Command(
        "clear_soft_limits",
        CONTROL,
        "remove the device's soft limits",
        served=Served("clear_soft_limits", lease=_CHECK),
    ),
    Command(
        "set_device_tag",
        CONTROL,
        "store a user-defined name in the device",
        (Param("tag", TEXT),),
        served=Served("set_device_tag", lease=_CHECK),
    ),
    Command("close", CONTROL, "end the session and release the transport (the jaws stay where they are)"),
    # -- queries ---------------------------------------------------------------------------------------------
    Command(
        "state", QUERY, "the jaws now: width, speed, force, grasp state, faults", served=Served("state", KEY)
    ),
    Command("info", QUERY, "what the device is, and the limits in force", served=Served("info", KEY)),
    Command("temperature", QUERY, "the gripper's temperature in °C", served=Served("temperature")),
    Command("device_tag", QUERY, "the user-defined name stored in the device", served=Served("device_tag")),
    Command(
        "check",
        QUERY,
        "validate values against the limits without sending anything (a dry run)",
        (
            _width(None),
            _SPEED,
            _FORCE,
            Param("command", TEXT, "", "check", keyword_only=True),
        ),
        aio=PLAIN,
    ),
    Command(
        "require",
        QUERY,
        "NotSupported unless the device has a capability",
        (Param("capability", OTHER), Param("command", TEXT)),
        aio=PLAIN,
    ),
    # -- streams ---------------------------------------------------------------------------------------------
    Command(
        "servo",
        STREAM,
        "head for a width now, without waiting: streamed targets, the latest wins",
        (_width(), _SPEED, _FORCE),
        served=Served("servo", lease=_TAKE),
    ),
    Command(
        "servo_flush",
        QUERY,
        "wait until the servo targets given so far are on the wire (True) or the timeout passed (False)",
        (Param("timeout", NUMBER, "s", 5.0),),
    ),
    Command(
        "stream",
        STREAM,
        "states at a rate; the asyncio twin is an async iterator: no callback, its loop body is one",
        (Param("rate_hz", NUMBER, "Hz", 50.0), Param("callback", OTHER, "", None)),
        aio=ITERATE,
        served=Served("state", SUBSCRIPTION),
        aio_omits=("callback",),
    ),
    Command(
        "on_connection",
        STREAM,
        "call back when the link is lost or back; returns what unregisters it",
        (Param("callback", OTHER),),
        aio=PLAIN,
    ),
)

COMMANDS: dict[str, Command] = {c.name: c for c in _TABLE}
"""Every public command of a Gripper, by method name."""

FACE_HOOKS: dict[str, str] = {
    "async_support": "the declared hook of the asyncio face (grippers/face_support.py), not a command",
}
"""Public Gripper methods that are no command: the seams the faces are built on."""


def motions() -> tuple[str, ...]:
    """The motion commands, in table order."""
    return tuple(c.name for c in _TABLE if c.kind == MOTION)


def served(how: str = VERB) -> dict[str, Command]:
    """The commands ``grippers serve`` offers in the way ``how``, by their verb."""
    return {c.served.verb: c for c in _TABLE if c.served is not None and c.served.how == how}
