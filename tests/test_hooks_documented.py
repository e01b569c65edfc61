"""The device contract is described where a vendor reads it (issue 40, "what to build" 1).

A plugin is written from docs/backends.md, docs/backend-kit.md and ``examples/acme_r1`` alone. So:

- every public hook of :class:`grippers.backends.CommandHooks` (the one object a family offers the commands,
  issue 40 §2) and every name the library asks a backend for (``backend.NAME``, ``getattr``/``hasattr`` on
  a backend) has its own entry in backends.md's "Hooks the commands call" (or is one of the three required
  names), and every entry there is one of them: no hook only in the source, none only in the docs;
- every public member of the device contract (``grippers.device``) and of the backend protocols is named on
  the page;
- the pages name no module a plugin may not import, and the worked example imports none: the public
  modules are the page's table, which must be the list below (adding a module to the contract is a
  decision, made here and on the page together);
- the dissector's record takes ``raw`` in one form, hex text, and the worked example writes it so.
"""

from __future__ import annotations

import ast
import importlib
import inspect
import re
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parent.parent
BACKENDS_MD = ROOT / "docs" / "backends.md"
KIT_MD = ROOT / "docs" / "backend-kit.md"
EXAMPLE = ROOT / "examples" / "acme_r1" / "acme_r1"

# What a plugin may import (the table "A plugin imports from these public modules only" of backends.md).
PUBLIC_MODULES = {
    "grippers",
    "grippers.aio",
    "grippers.backends",
    "grippers.device",
    "grippers.drivers.links",
    "grippers.drivers.simkit",
    "grippers.kit",
    "grippers.kit.motion",
    "grippers.profiles",
    "grippers.settings",
    "grippers.streams",
    "grippers.testing",
    "grippers.testing.conformance",
    "grippers.urls",
}
REQUIRED = {"family", "profile_model", "open"}  # grippers.backends.Backend: "The backend" section

# getattr(backend, "url_protocols", ...), backend.simulator(...)
ASKED = (
    re.compile(r"\b(?:getattr|hasattr)\(\s*backend\s*,\s*\"(\w+)\""),
    re.compile(r"\bbackend\.([a-z_]\w*)\b"),
)


def _section(text: str, heading: str) -> str:
    start = text.index(f"\n## {heading}\n")
    end = text.find("\n## ", start + 1)
    return text[start : end if end != -1 else len(text)]


def command_hooks() -> set[str]:
    """The public members of CommandHooks: every hook a family may override."""
    from grippers.kit import CommandHooks

    return {name for name in dir(CommandHooks) if not name.startswith("_")}


def asked_hooks() -> dict[str, str]:
    """Every name the package asks of a backend, with the first place that asks it, and every command hook
    (asked through ``commands_of(backend)``)."""
    found: dict[str, str] = dict.fromkeys(command_hooks(), "grippers/backends/command_hooks.py")
    for path in sorted((ROOT / "grippers").rglob("*.py")):
        for number, line in enumerate(path.read_text().splitlines(), 1):
            for pattern in ASKED:
                for name in pattern.findall(line):
                    found.setdefault(name, f"{path.relative_to(ROOT)}:{number}")
    return found


def documented_hooks() -> set[str]:
    """The names of the "Hooks the commands call" entries: ``### `a`, `b` `` headings."""
    section = _section(BACKENDS_MD.read_text(), "Hooks the commands call")
    names: set[str] = set()
    for heading in re.findall(r"^### (.+)$", section, re.MULTILINE):
        names.update(re.findall(r"`(\w+)`", heading))
    return names


def test_the_scan_finds_the_hooks_it_must() -> None:
    """The scan itself can fail: it finds the hooks we know the commands ask, at their places."""
    asked = asked_hooks()
    assert {"dissector", "probe_candidates", "read_settings", "selftest_checks", "simulator"} <= set(asked)
    assert {"commands", "url_protocols"} <= set(asked)  # asked of the backend itself
    assert asked["simulator"].startswith("grippers/"), asked["simulator"]


def test_every_hook_the_library_asks_for_is_described() -> None:
    missing = {
        name: where for name, where in asked_hooks().items() if name not in documented_hooks() | REQUIRED
    }
    assert not missing, f"asked of a backend but not described in docs/backends.md: {missing}"


def test_every_described_hook_is_asked_for() -> None:
    stale = documented_hooks() - set(asked_hooks())
    assert not stale, f"described in docs/backends.md but asked nowhere: {sorted(stale)}"


def test_every_entry_says_what_it_is_and_shows_it() -> None:
    """An entry of one hook has a signature or a value, when it is read, and an example."""
    section = _section(BACKENDS_MD.read_text(), "Hooks the commands call")
    # The entries after the intro and "What the hooks receive".
    entries = re.split(r"^### ", section, flags=re.MULTILINE)[2:]
    assert len(entries) >= 12
    for entry in entries:
        heading, _, body = entry.partition("\n")
        assert re.search(r"\b(called|read)\b", body), f"{heading}: when is it called?"
        example = re.search(r"The (WSG|MSG|ACME R1)'s", body)
        assert "```" in body or example or "`{" in body, f"{heading}: no example"


def _public_members(cls: type) -> list[str]:
    return [name for name in vars(cls) if not name.startswith("_")]


def test_the_device_contract_and_the_backend_protocols_are_named_on_the_page() -> None:
    import grippers.backends as backends
    import grippers.device as device
    import grippers.kit as kit

    text = BACKENDS_MD.read_text()
    classes = [getattr(device, name) for name in device.__all__ if inspect.isclass(getattr(device, name))]
    classes += [
        backends.Backend,
        backends.SimulatedBackend,
        backends.BusSimulatedBackend,
        kit.CommandHooks,
    ]
    missing = [
        f"{cls.__name__}.{name}"
        for cls in classes
        for name in _public_members(cls)
        if not re.search(rf"`[^`\n]*\b{name}\b[^`\n]*`", text)
    ]
    assert not missing, f"public members of the contract not named in docs/backends.md: {missing}"


def _module_of(dotted: str) -> str | None:
    """The longest importable module prefix of ``grippers.a.b.c`` (an attribute may follow it)."""
    parts = dotted.split(".")
    for n in range(len(parts), 0, -1):
        name = ".".join(parts[:n])
        try:
            importlib.import_module(name)
        except ImportError:
            continue
        return name
    return None


@pytest.mark.parametrize("page", [BACKENDS_MD, KIT_MD], ids=lambda p: p.name)
def test_the_pages_name_only_public_modules(page: Path) -> None:
    # grippers.X as an import name; not a file (acme_grippers.py), a path or a schema id (grippers.monitor/1).
    named = set(re.findall(r"(?<![\w/.-])(grippers(?:\.[a-z_]\w*)+)(?![\w/-])", page.read_text()))
    assert named, "the scan found no module names at all"
    private = {dotted: _module_of(dotted) for dotted in named if _module_of(dotted) not in PUBLIC_MODULES}
    assert not private, f"{page.name} names modules a plugin may not import: {private}"


def test_the_public_modules_table_is_the_list() -> None:
    table = BACKENDS_MD.read_text().partition("A plugin imports from these public modules only")[2]
    table = table.partition("\n\n| module |")[2].partition("\n\n")[0]
    listed = {
        name
        for row in table.splitlines()[2:]
        for name in re.findall(r"`(grippers[\w.]*)`", row.split("|")[1])
    }
    assert listed == PUBLIC_MODULES


def test_the_worked_example_imports_only_public_modules() -> None:
    imported: set[str] = set()
    for path in EXAMPLE.rglob("*.py"):
        for node in ast.walk(ast.parse(path.read_text())):
            if isinstance(node, ast.ImportFrom) and node.module and node.level == 0:
                imported.add(node.module)
            elif isinstance(node, ast.Import):
                imported.update(alias.name for alias in node.names)
    ours = {name for name in imported if name.split(".")[0] == "grippers"}
    assert "grippers.kit" in ours  # the scan reads the example's imports
    assert ours <= PUBLIC_MODULES, sorted(ours - PUBLIC_MODULES)


def test_the_kit_exports_what_a_plugin_needs() -> None:
    import grippers.kit as kit

    for name in (
        "ProbeCandidate",
        "RawProbe",
        "Identity",
        "bus_query",
        "Dissector",
        "CanDissector",
        "monitor_record",
    ):
        assert name in kit.__all__ and getattr(kit, name) is not None
    assert kit.ServoTarget(0.05, 0.1, None).force is None


def test_a_record_takes_raw_as_hex_text_only() -> None:
    from grippers.kit import monitor_record

    assert monitor_record(protocol="acme", raw="520401ff")["raw"] == "520401ff"
    with pytest.raises(TypeError, match="hex"):
        monitor_record(protocol="acme", raw=b"R\x04\x01")


def test_the_worked_example_dissects_into_hex(monkeypatch) -> None:
    monkeypatch.syspath_prepend(str(EXAMPLE.parent))
    monkeypatch.delitem(sys.modules, "acme_r1", raising=False)
    monkeypatch.delitem(sys.modules, "acme_r1.codec", raising=False)
    codec = importlib.import_module("acme_r1.codec")
    frame = codec.Frame("R", codec.Reg.STATUS, count=2)
    dissector = codec.AcmeDissector()
    records = dissector.feed("host->gripper", frame.encode(), 1.0)
    assert [r["raw"] for r in records] == [frame.encode().hex()]
    garbled = dissector.feed("gripper->host", b"r\x04\x01\x00\x00\x00", 2.0)  # a bad checksum
    assert garbled and all(isinstance(r["raw"], str) for r in garbled)
