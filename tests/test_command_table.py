"""grippers/commands.py declares every public Gripper command once; each face follows it (issue 32 §3).

What is derived from the table (the remote protocol's verbs, the server's dispatch, the asyncio face's
forwarding methods) is checked here for what derivation cannot promise: that the table says what the
Gripper really has, that every method has its asyncio twin with the same parameters, that the remote client
sends each served verb with the table's arguments, and that the CLI's motion commands are the table's.
No device and no network: signatures, a parser, and a remote client whose one sending call is recorded.
"""

from __future__ import annotations

import argparse
import inspect
import threading
from typing import Any

import pytest

from grippers import commands
from grippers.aio import AsyncGripper
from grippers.cli import SUBCOMMANDS
from grippers.cli import motion as cli_motion
from grippers.commands import COMMANDS, FACE_HOOKS, Command
from grippers.device import DeviceContext
from grippers.errors import GripperError
from grippers.gripper import Capability, Gripper
from grippers.profiles import load_profile
from grippers.remote import protocol
from grippers.remote.client import RemoteDevice, RemoteGripper
from grippers.remote.holder import LossListeners
from grippers.remote.link import ServedLink

_KIND = {False: inspect.Parameter.POSITIONAL_OR_KEYWORD, True: inspect.Parameter.KEYWORD_ONLY}


def _public_methods(cls: type) -> set[str]:
    return {
        name
        for name in dir(cls)
        if not name.startswith("_") and inspect.isfunction(inspect.getattr_static(cls, name))
    }


def _params(fn: Any) -> list[tuple[str, Any, Any]]:
    """(name, default, kind) of every parameter but ``self``."""
    sig = inspect.signature(fn)
    return [(p.name, p.default, p.kind) for p in list(sig.parameters.values())[1:]]


def _declared(c: Command, omit: tuple[str, ...] = ()) -> list[tuple[str, Any, Any]]:
    return [
        (p.name, inspect.Parameter.empty if p.required else p.default, _KIND[p.keyword_only])
        for p in c.params
        if p.name not in omit
    ]


def test_every_public_gripper_method_is_in_the_table() -> None:
    public = _public_methods(Gripper)
    assert public - set(COMMANDS) - set(FACE_HOOKS) == set(), "public Gripper methods the table lacks"
    assert set(COMMANDS) - public == set(), "the table declares methods Gripper does not have"
    assert set(FACE_HOOKS) <= public


@pytest.mark.parametrize("name", list(COMMANDS))
def test_the_table_gives_the_gripper_methods_own_parameters(name: str) -> None:
    assert _params(getattr(Gripper, name)) == _declared(COMMANDS[name])


@pytest.mark.parametrize("name", list(COMMANDS))
def test_every_command_has_its_asyncio_twin_with_the_same_parameters(name: str) -> None:
    c = COMMANDS[name]
    twin = getattr(AsyncGripper, name, None)
    assert twin is not None, f"grippers/aio.py has no {name}()"
    if c.aio == commands.AWAIT:
        assert inspect.iscoroutinefunction(twin), f"AsyncGripper.{name} must be awaitable"
    elif c.aio == commands.ITERATE:
        assert inspect.isasyncgenfunction(twin), f"AsyncGripper.{name} must be an async iterator"
    else:
        assert not inspect.iscoroutinefunction(twin) and not inspect.isasyncgenfunction(twin)
    assert _params(twin) == _declared(c, c.aio_omits)


def test_the_asyncio_face_uses_no_private_member_of_the_gripper() -> None:
    """Only public methods and the declared hook (``async_support()``): ``sync._x`` / ``gripper._x`` /
    ``g._x`` appear nowhere in grippers/aio.py's code."""
    import re

    import grippers.aio

    source = inspect.getsource(grippers.aio)
    assert re.findall(r"\b(?:sync|gripper|g)\._[a-z]\w*", source) == []


def test_every_served_verb_calls_its_method_with_the_wire_arguments() -> None:
    """The server's dispatch is ``getattr(g, name)(**args)``: each verb's arguments must bind."""
    verbs = commands.served()
    assert set(protocol.COMMANDS) == {*verbs, "control"}
    for verb, c in verbs.items():
        spec = protocol.COMMANDS[verb]
        assert spec.args == c.wire_args and spec.motion == (c.kind == commands.MOTION)
        inspect.signature(getattr(Gripper, c.name)).bind(None, **{a: 0.0 for a in spec.args})
    keys = {c.served.verb for c in COMMANDS.values() if c.served and c.served.how != commands.VERB}
    assert keys == {"state", "info"}  # read on their own keys (protocol.state_key, info_key), not as verbs


# -- the remote client ------------------------------------------------------------------------------------


class _RecordingLink(ServedLink):
    """A served link with no Zenoh session: its one sending call records the verb and arguments."""

    def __init__(self) -> None:  # noqa: D107 - no session
        self.url, self.served_name = "zenoh://recorded", "recorded"  # a served name is one key chunk
        self.timeout = 1.0
        self.context = DeviceContext(name=self.url)
        self.lost = None
        self._listeners = LossListeners()
        self.info_doc = {
            "profile_data": load_profile("wsg-50").model_dump(mode="json"),
            "limits": load_profile("wsg-50").limits().model_dump(mode="json"),
            "capabilities": [c.value for c in Capability],
        }
        self.sent: list[tuple[str, dict[str, Any]]] = []
        self.sent_lock = threading.Lock()

    def call(self, command: str, args: dict[str, Any] | None = None, timeout: float | None = None) -> Any:
        with self.sent_lock:
            self.sent.append((command, dict(args or {})))
        if command == "grasp":
            return {"grasped": True, "width": 0.02, "force": 10.0, "state": "holding", "reason": None}
        if command in ("move", "release"):
            return {"width": 0.05, "state": "idle"}
        return {"temperature": 30.0, "device_tag": "tag"}.get(command)

    def read(self, key: str, command: str) -> Any:  # a key read, not a verb: the grasp asks it first
        raise GripperError("no state here", device=self.name, command="state")

    def close(self) -> None:
        pass


class _Recording(RemoteGripper):
    """A remote client over a :class:`_RecordingLink`."""

    def __init__(self) -> None:  # noqa: D107
        self.link = _RecordingLink()
        device = RemoteDevice(self.link)
        super().__init__(device, device.profile, "zenoh://recorded", timeout=1.0)
        self.sent = self.link.sent
        self.sent_lock = self.link.sent_lock


_SAMPLE = {"width": 0.03, "min_width": 0.01, "max_width": 0.06, "tag": "cell 3"}


@pytest.mark.parametrize("verb", list(commands.served()))
def test_the_remote_client_sends_each_served_verb_with_the_tables_arguments(verb: str) -> None:
    c = commands.served()[verb]
    g = _Recording()
    try:
        kwargs = {p.name: _SAMPLE[p.name] for p in c.params if p.required}
        getattr(g, c.name)(**kwargs)
        if c.name == "servo":
            assert g.servoing and g.servo_flush(5.0)
        with g.sent_lock:
            sent = list(g.sent)
        assert sent and sent[-1][0] == verb, f"{c.name}() sent {sent}, the table says {verb!r}"
        assert set(sent[-1][1]) == set(c.wire_args)
    finally:
        g.close()


def test_the_remote_client_refuses_to_send_arguments_the_table_does_not_list() -> None:
    g = _Recording()
    try:
        with pytest.raises(GripperError, match="the command table says"):
            g.link.command("move", 1.0, width=0.02, speed=0.1)  # no timeout: not what the table says
        assert g.sent == []
    finally:
        g.close()


# -- the command line -------------------------------------------------------------------------------------


def _cli_motion_commands() -> dict[str, cli_motion.MotionCommand]:
    return {
        name: getattr(cli_motion, spec.split(":", 1)[1])
        for name, spec in SUBCOMMANDS.items()
        if spec.startswith(".motion:")
    }


def test_the_cli_motion_commands_are_the_tables() -> None:
    cli = _cli_motion_commands()
    called = {line.split()[0] for c in COMMANDS.values() for line in c.cli}
    assert set(cli) == called
    assert commands.motions() == cli_motion.MOTIONS
    for name in commands.motions():
        assert COMMANDS[name].cli == (name,), f"the motion {name} has no `grippers {name}`"


@pytest.mark.parametrize("name", commands.motions())
def test_each_cli_motion_takes_the_tables_parameters(name: str) -> None:
    parser = argparse.ArgumentParser()
    _cli_motion_commands()[name].add_arguments(parser)
    dests = {a.dest for a in parser._actions}
    for p in COMMANDS[name].params:
        if p.sent:
            assert ("motion_timeout" if p.name == "timeout" else p.name) in dests, (name, p.name)


def test_the_flags_the_table_names_exist() -> None:
    cli = _cli_motion_commands()
    for c in COMMANDS.values():
        for line in c.cli:
            word, *flags = line.split()
            parser = argparse.ArgumentParser()
            cli[word].add_arguments(parser)
            options = {o for a in parser._actions for o in a.option_strings}
            assert set(flags) <= options, line


# -- the documentation ------------------------------------------------------------------------------------

_LEASE_WORDS = {
    "takes": "take",
    "never refused": "free",
    "free": "free",
    "refused if another client holds it": "check",
}


def test_docs_remote_md_lists_the_served_verbs_as_the_table_does() -> None:
    """docs/remote.md's command table (for programs in other languages) says what the table says."""
    import re
    from pathlib import Path

    text = (Path(__file__).resolve().parents[1] / "docs" / "remote.md").read_text()
    documented: dict[str, tuple[dict[str, str], str]] = {}
    for line in text.splitlines():
        cells = [c.strip() for c in line.strip().strip("|").split("|")]
        if len(cells) != 4 or not cells[0].startswith("`") or cells[0].startswith("`grippers/"):
            continue
        args = {m.group(1): "number?" if m.group(2) else "?" for m in re.finditer(r"`(\w+)(\?)?`", cells[1])}
        for name in re.findall(r"`(\w+)`", cells[0]):
            documented[name] = (args, cells[2])
    documented.pop("control", None)
    assert set(documented) == set(commands.served())
    for verb, (args, lease) in documented.items():
        spec = protocol.COMMANDS[verb]
        assert set(args) == set(spec.args), verb
        assert {a for a, k in args.items() if k == "number?"} == {
            a for a, k in spec.args.items() if k == "number?"
        }, verb
        assert _LEASE_WORDS[lease] == spec.lease, verb
