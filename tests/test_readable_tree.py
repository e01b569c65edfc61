"""Issue 40 §6, "the tree stays readable": one place for a unit conversion, one grammar for a URL.

Read off the source (its syntax tree), in the spirit of tests/test_import_graph.py: a rule that holds only
by habit drifts, and every copy we found of a conversion or of a URL parser had drifted into a bug (a
``#fragment`` kept by one reader and dropped by another, a lease in seconds where Zenoh wants milliseconds).

- **Units.** The generic modules (everything in ``grippers/`` but the backends) convert millimetres,
  milliamperes, milliseconds and nanoseconds through :mod:`grippers.units` only: no ``* 1000``, ``/ 1e3``,
  ``* 1e-3``, ``% 1000`` or ``divmod(t, 1_000_000_000)`` of their own. The backends and ``drivers/`` are
  where a device's own units (mm, µm, mA, mV, ms) meet the API's SI (docs/DEVELOPING.md), and are not read.
- **URLs.** Outside the grammar (``drivers/urls.py`` and its API face ``grippers/urls.py``) nobody splits a
  scheme (``"://"``), a host from its port (``rpartition(":")``, ``strip("[]")``), parses or builds a query
  by hand or with ``urllib.parse``, or calls the grammar's low-level ``parse_query``: they call its readers
  (``parse_url``, ``scheme_of``, ``is_url``, ``parse_address``, ``zenoh_endpoints``, ``web_fields``,
  ``on_transport``, ``with_params``, ``append_params`` ...).

Each exception is listed below with its reason; a new one is a decision, made here, not a habit.
"""

from __future__ import annotations

import ast
from collections.abc import Iterator
from dataclasses import dataclass
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parent.parent
SOURCES = ("grippers", "drivers")

# --- units -------------------------------------------------------------------------------------------------

UNITS_MODULE = "grippers/units.py"
# Where a device's own units meet SI: the backends (one per family) and everything in drivers/.
DEVICE_UNITS = ("grippers/backends/", "drivers/")
# The factors of a unit conversion between SI and its milli-, micro- or nano- form.
FACTORS = {1000, 1e-3, 1e6, 1e-6, 1e9, 1e-9}
# A factor this big or small in a call (``si("width_mm", 1e-3)``) is a conversion too; 1e-6 is the usual
# epsilon of ``max(speed, 1e-6)`` and is not.
CALL_FACTORS = {1000, 1e-3, 1e9}
SCALING = (ast.Mult, ast.Div, ast.FloorDiv, ast.Mod)
UNIT_EXCEPTIONS: dict[str, str] = {}  # path: why (none today)

# --- URLs --------------------------------------------------------------------------------------------------

GRAMMAR = ("drivers/urls.py", "grippers/urls.py")
GRAMMAR_MODULES = ("urls",)  # ``from .urls import``, ``from grippers.drivers.urls import``, ...
# The grammar's pieces below its readers: what a caller uses one of the readers for instead.
PRIMITIVES = {"parse_query"}
# String methods that split or test text, and the arguments that make them a hand-written URL parser.
SPLITTERS = {
    "partition",
    "rpartition",
    "split",
    "rsplit",
    "startswith",
    "endswith",
    "removeprefix",
    "replace",
}
HOST_PORT_SPLITTERS = {"rpartition", "rsplit"}  # text.rpartition(":"): HOST:PORT by hand
QUERY_SPLITTERS = {"partition", "rpartition", "split", "rsplit"}  # url.partition("?"): a query by hand
URL_EXCEPTIONS = {
    # A typo corrector: it reads the text the grammar refused (``wsg+tpc:/host``, ``10.0.0.5:1000``) to
    # guess what the user meant, so it cannot ask the grammar; what it suggests is then parsed by it.
    "grippers/cli/suggest.py": "guesses a URL from text the grammar refused",
}


@dataclass(frozen=True)
class Finding:
    path: str
    line: int
    what: str

    def __str__(self) -> str:
        return f"{self.path}:{self.line}: {self.what}"


def _modules() -> Iterator[tuple[str, ast.Module]]:
    for folder in SOURCES:
        for path in sorted((ROOT / folder).rglob("*.py")):
            rel = path.relative_to(ROOT).as_posix()
            yield rel, ast.parse(path.read_text(encoding="utf-8"), filename=rel)


def _number(node: ast.AST) -> float | None:
    if isinstance(node, ast.Constant) and type(node.value) in (int, float):
        return float(node.value)
    return None


def unit_conversions(path: str, tree: ast.AST) -> list[Finding]:
    """Every ``x * 1000``-style conversion in ``tree``."""
    found = []
    for node in ast.walk(tree):
        if isinstance(node, ast.BinOp) and isinstance(node.op, SCALING):
            for side in (node.left, node.right):
                if _number(side) in FACTORS:
                    found.append(Finding(path, node.lineno, f"{ast.unparse(node)[:80]}: use grippers.units"))
                    break
        # positional arguments only: a keyword (maxlen=1000) is a count, not a factor
        elif isinstance(node, ast.Call) and any(_number(a) in CALL_FACTORS for a in node.args):
            found.append(Finding(path, node.lineno, f"{ast.unparse(node)[:80]}: use grippers.units"))
    return found


def _text(node: ast.AST) -> str | None:
    return node.value if isinstance(node, ast.Constant) and isinstance(node.value, str) else None


def url_parsing(path: str, tree: ast.AST) -> list[Finding]:
    """Every piece of URL parsing in ``tree`` that is not a call of the grammar's readers."""
    found = []

    def add(node: ast.AST, what: str) -> None:
        found.append(Finding(path, getattr(node, "lineno", 0), what))

    for node in ast.walk(tree):
        if isinstance(node, ast.ImportFrom):
            module = node.module or ""
            if module == "urllib.parse" or module.startswith("urllib.parse."):
                add(node, f"imports urllib.parse ({', '.join(a.name for a in node.names)}): use the grammar")
            elif module.rsplit(".", 1)[-1] in GRAMMAR_MODULES:
                for alias in node.names:
                    if alias.name in PRIMITIVES or alias.name.startswith("_"):
                        add(node, f"imports the grammar's primitive {alias.name}: call one of its readers")
        elif isinstance(node, ast.Import):
            for alias in node.names:
                if alias.name.startswith("urllib.parse"):
                    add(node, "imports urllib.parse: use the grammar")
        elif isinstance(node, ast.Attribute) and node.attr in PRIMITIVES:
            add(node, f"calls the grammar's primitive {node.attr}: call one of its readers")
        elif isinstance(node, ast.Compare):
            if any("://" in (_text(part) or "") for part in (node.left, *node.comparators)):
                add(node, f"{ast.unparse(node)[:60]}: a scheme tested by hand (is_url, scheme_of)")
        elif isinstance(node, ast.Call) and isinstance(node.func, ast.Attribute) and node.args:
            method, first = node.func.attr, _text(node.args[0]) or ""
            texts = (
                [_text(e) or "" for e in node.args[0].elts]
                if isinstance(node.args[0], ast.Tuple)
                else [first]
            )
            if method in SPLITTERS and any("://" in t for t in texts):
                add(node, f"{ast.unparse(node)[:60]}: a scheme split by hand (scheme_of, on_transport)")
            elif method in QUERY_SPLITTERS and first == "?":
                add(node, f"{ast.unparse(node)[:60]}: a query split by hand (web_target, with_query)")
            elif method in HOST_PORT_SPLITTERS and first == ":":
                add(node, f"{ast.unparse(node)[:60]}: HOST:PORT split by hand (parse_address)")
            elif method in ("strip", "lstrip", "rstrip") and "[" in first:
                add(node, f"{ast.unparse(node)[:60]}: IPv6 brackets by hand (parse_address)")
    return found


def _outside(path: str, places: tuple[str, ...]) -> bool:
    return not any(path == p or (p.endswith("/") and path.startswith(p)) for p in places)


def conversions_in_generic_modules() -> list[Finding]:
    return [
        f
        for path, tree in _modules()
        if path.startswith("grippers/") and _outside(path, (UNITS_MODULE, *DEVICE_UNITS))
        if path not in UNIT_EXCEPTIONS
        for f in unit_conversions(path, tree)
    ]


def url_parsing_outside_the_grammar() -> list[Finding]:
    return [
        f
        for path, tree in _modules()
        if _outside(path, GRAMMAR) and path not in URL_EXCEPTIONS
        for f in url_parsing(path, tree)
    ]


def test_generic_modules_convert_units_through_grippers_units() -> None:
    found = conversions_in_generic_modules()
    assert not found, "unit conversions outside grippers/units.py:\n" + "\n".join(map(str, found))


def test_only_the_grammar_parses_urls() -> None:
    found = url_parsing_outside_the_grammar()
    assert not found, "URL parsing outside drivers/urls.py:\n" + "\n".join(map(str, found))


def test_every_exception_is_still_needed() -> None:
    """An exception whose file no longer breaks the rule (or is gone) is removed from the list."""
    modules = dict(_modules())
    for path in URL_EXCEPTIONS:
        assert path in modules and url_parsing(path, modules[path]), f"{path}: no longer an exception"
    for path in UNIT_EXCEPTIONS:
        assert path in modules and unit_conversions(path, modules[path]), f"{path}: no longer an exception"


SNIPPETS_CONVERTING = [
    "width_mm = width * 1000",
    "w = v['width_mm'] / 1000.0",
    "lease = int(lease_s * 1e3)",
    "ms = int(t * 1000) % 1000",
    "a = ma * 0.001",
    "sec, ns = divmod(stamp, 1_000_000_000)",
    "row = si('width_mm', 1e-3)",
]
SNIPPETS_PARSING = [
    "scheme = url.partition('://')[0]",
    "ok = '://' in text",
    "bare = text.lower().startswith('can://')",
    "shared = port.startswith(('loop://', 'socket://'))",
    "host, _, port = text.rpartition(':')",
    "host = host.strip('[]')",
    "base = url.split('?')[0]",
    "from urllib.parse import quote",
    "import urllib.parse",
    "from grippers.drivers.urls import parse_query",
    "from ..urls import _host_port",
    "q = urls.parse_query(u, text)",
]


@pytest.mark.parametrize("source", SNIPPETS_CONVERTING)
def test_the_unit_check_finds_a_conversion(source: str) -> None:
    assert unit_conversions("x.py", ast.parse(source))


@pytest.mark.parametrize("source", SNIPPETS_PARSING)
def test_the_url_check_finds_hand_parsing(source: str) -> None:
    assert url_parsing("x.py", ast.parse(source))


@pytest.mark.parametrize(
    "source",
    [
        "w = to_mm(width)",
        "t = 2.0 * d / max(speed, 1e-6)",  # an epsilon, not a factor
        "MARGIN = 0.001",  # a constant in SI
        "u = parse_url(text)",
        "s = scheme_of(text) == 'can'",
        "url = f'tcp://{host}:{port}'",  # formatting a URL is not parsing one
        "module, _, name = spec.partition(':')",  # an entry point's module:attribute
    ],
)
def test_the_checks_leave_the_readers_alone(source: str) -> None:
    tree = ast.parse(source)
    assert not unit_conversions("x.py", tree) and not url_parsing("x.py", tree)
