"""The package's import graph (grimp): no circles between modules, and the layers docs/DEVELOPING.md draws.

The graph is built from the package as it installs (``drivers/`` as ``grippers.drivers``), laid out with
symbolic links as scripts/installed-tree.sh does, in a child interpreter so the editable install's copy is
not the one grimp reads. Every import counts: module level, inside functions, and under ``TYPE_CHECKING``
(issue 32 names two type-only circles among those to remove: a type-only circle still means two modules that
cannot be understood, or split, one without the other).
"""

from __future__ import annotations

import json
import os
import subprocess
import sys
from collections.abc import Iterator
from pathlib import Path

import pytest

pytest.importorskip("grimp")

ROOT = Path(__file__).resolve().parent.parent

# Runs in the child: the graph as {importer: [[imported, line, contents], ...]}, external packages included
# (squashed to their top-level name: "socket", "can", "threading").
_DUMP = """
import json, sys, grimp
g = grimp.build_graph("grippers", include_external_packages=True, cache_dir=None)
out = {}
for m in sorted(g.modules):
    if g.is_module_squashed(m):
        continue
    rows = out.setdefault(m, [])
    for imported in sorted(g.find_modules_directly_imported_by(m)):
        for d in g.get_import_details(importer=m, imported=imported):
            rows.append([imported, d["line_number"], d["line_contents"]])
json.dump(out, sys.stdout)
"""

Graph = dict[str, list[list[object]]]

# Modules that do I/O, wait or keep time: a sans-IO core imports none of them (time is passed in).
IO_MODULES = {"socket", "serial", "can", "threading", "selectors", "asyncio", "subprocess", "time", "zenoh"}

# The sans-IO cores: bytes and times in, events and bytes out (docs/DEVELOPING.md "The shape in one picture").
SANS_IO = [
    "grippers.drivers.wsg.protocol",
    "grippers.drivers.wsg.commands",
    "grippers.drivers.wsg.session",
    "grippers.drivers.wsg.sim.model",
    "grippers.drivers.stepfoc.can_protocol",
    "grippers.drivers.stepfoc.can_session",
    "grippers.drivers.stepfoc.uart_protocol",
    "grippers.drivers.stepfoc.motion",
    "grippers.drivers.stepfoc.speed",
    "grippers.drivers.stepfoc.sim.model",
    "grippers.drivers.modbus",
    "grippers.drivers.modbus_tcp",
    "grippers.drivers.modbus_model",
    "grippers.drivers.robotiq.modbus",
    "grippers.drivers.robotiq.registers",
    "grippers.drivers.robotiq.session",
    "grippers.drivers.robotiq.urcap_protocol",
    "grippers.drivers.robotiq.sim.model",
    "grippers.drivers.replay",
]


@pytest.fixture(scope="module")
def graph(tmp_path_factory: pytest.TempPathFactory) -> Graph:
    tree = tmp_path_factory.mktemp("installed")
    (tree / "grippers").mkdir()
    for entry in (ROOT / "grippers").iterdir():
        if entry.name != "__pycache__":
            (tree / "grippers" / entry.name).symlink_to(entry)
    (tree / "grippers" / "drivers").symlink_to(ROOT / "drivers")
    (tree / "grippers" / "_profiles").symlink_to(ROOT / "profiles")
    env = {**os.environ, "PYTHONPATH": str(tree)}
    done = subprocess.run(
        [sys.executable, "-c", _DUMP], env=env, cwd=tree, capture_output=True, text=True, timeout=120
    )
    assert done.returncode == 0, done.stderr
    result: Graph = json.loads(done.stdout)
    assert "grippers.drivers.wsg.session" in result, "the installed layout was not the one read"
    return result


def _edges(graph: Graph, module: str) -> set[str]:
    return {str(row[0]) for row in graph.get(module, [])}


def _line(graph: Graph, importer: str, imported: str) -> str:
    rows = [r for r in graph[importer] if r[0] == imported]
    return "; ".join(f"line {r[1]}: {r[2]}" for r in rows)


def _cycles(graph: Graph) -> list[list[str]]:
    """The strongly connected components (Tarjan, iterative) of more than one module among our modules."""
    ours = {m: {x for x in _edges(graph, m) if x in graph} for m in graph}
    index: dict[str, int] = {}
    low: dict[str, int] = {}
    stack: list[str] = []
    on_stack: set[str] = set()
    found: list[list[str]] = []
    for start in sorted(ours):
        if start in index:
            continue
        work: list[tuple[str, Iterator[str]]] = [(start, iter(sorted(ours[start])))]
        index[start] = low[start] = len(index)
        stack.append(start)
        on_stack.add(start)
        while work:
            v, it = work[-1]
            w = next(it, None)
            if w is not None:
                if w not in index:
                    index[w] = low[w] = len(index)
                    stack.append(w)
                    on_stack.add(w)
                    work.append((w, iter(sorted(ours[w]))))
                elif w in on_stack:
                    low[v] = min(low[v], index[w])
                continue
            work.pop()
            if work:
                low[work[-1][0]] = min(low[work[-1][0]], low[v])
            if low[v] == index[v]:
                component = []
                while True:
                    w = stack.pop()
                    on_stack.discard(w)
                    component.append(w)
                    if w == v:
                        break
                if len(component) > 1:
                    found.append(sorted(component))
    return found


def _describe(graph: Graph, component: list[str]) -> str:
    inside = set(component)
    lines = [" <-> ".join(component)]
    for a in component:
        for b in sorted(_edges(graph, a) & inside):
            lines.append(f"    {a} -> {b} ({_line(graph, a, b)})")
    return "\n".join(lines)


def _upstream(graph: Graph, module: str) -> dict[str, list[str]]:
    """Every module ``module`` imports, directly or not, with one chain that leads to it (breadth first)."""
    chains = {module: [module]}
    queue = [module]
    while queue:
        m = queue.pop(0)
        for x in sorted(_edges(graph, m)):
            if x not in chains:
                chains[x] = [*chains[m], x]
                if x in graph:
                    queue.append(x)
    del chains[module]
    return chains


def _chain(graph: Graph, chain: list[str]) -> str:
    return " -> ".join(chain) + f"  ({_line(graph, chain[-2], chain[-1])})"


def test_no_import_circles(graph: Graph) -> None:
    cycles = _cycles(graph)
    assert not cycles, "import circles between modules:\n" + "\n".join(_describe(graph, c) for c in cycles)


def test_the_cycle_search_finds_a_circle() -> None:
    """The search itself: a circle of three and a type-only pair are found, a chain is not."""
    fake: Graph = {
        "a": [["b", 1, "import b"]],
        "b": [["c", 1, "import c"]],
        "c": [["a", 3, "from a import A  # TYPE_CHECKING"]],
        "d": [["a", 1, "import a"], ["e", 1, "import e"]],
        "e": [["d", 9, "from d import D"]],
        "f": [["a", 1, "import a"]],
    }
    assert _cycles(fake) == [["a", "b", "c"], ["d", "e"]]
    assert "c -> a (line 3: from a import A  # TYPE_CHECKING)" in _describe(fake, ["a", "b", "c"])


def test_drivers_never_import_the_api_layer(graph: Graph) -> None:
    bad = [
        _chain(graph, [m, x])
        for m in graph
        if m.startswith("grippers.drivers")
        for x in _edges(graph, m)
        if (x == "grippers" or x.startswith("grippers.")) and not x.startswith("grippers.drivers")
    ]
    assert not bad, "drivers/ imports the API layer:\n" + "\n".join(sorted(bad))


@pytest.mark.parametrize("core", SANS_IO)
def test_sans_io_cores_import_nothing_that_does_io(graph: Graph, core: str) -> None:
    assert core in graph, f"{core} is gone: update SANS_IO and docs/DEVELOPING.md"
    bad = [_chain(graph, chain) for x, chain in _upstream(graph, core).items() if x in IO_MODULES]
    assert not bad, f"{core} reaches I/O:\n" + "\n".join(sorted(bad))


def test_drivers_never_import_simulators(graph: Graph) -> None:
    """A client never needs a simulator; the simulators reuse the clients' codecs, not the other way round."""

    def is_sim(m: str) -> bool:
        return ".sim." in m + "." and m.startswith("grippers.drivers.")

    bad = [  # the import that crosses into a simulator (anything that leads to it goes through one)
        _chain(graph, [m, x])
        for m in graph
        if m.startswith("grippers.drivers") and not is_sim(m)
        for x in _edges(graph, m)
        if is_sim(x)
    ]
    assert not bad, "a driver module imports a simulator:\n" + "\n".join(sorted(bad))
