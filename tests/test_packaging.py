"""Packaging and layering: only ``grippers`` at the top of site-packages, drivers below the API layer.

The drivers live in the repository's top-level ``drivers/`` folder (the product's layout) but install as
``grippers.drivers``, so a user's own ``drivers`` package can never shadow them (or be shadowed).
"""

from __future__ import annotations

import ast
import subprocess
import sys
import tomllib
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
SANS_IO = [
    "drivers/wsg/protocol.py",
    "drivers/wsg/commands.py",
    "drivers/wsg/session.py",
    "drivers/stepfoc/can_protocol.py",
    "drivers/stepfoc/can_session.py",
    "drivers/stepfoc/uart_protocol.py",
    "drivers/wsg/sim/model.py",
    "drivers/stepfoc/sim/model.py",
]
IO_MODULES = {"socket", "threading", "time", "select", "selectors", "serial", "can", "asyncio", "os", "zenoh"}


def _imports(path: Path) -> list[tuple[int, str]]:
    """(relative level, absolute module name) of every import in a file."""
    found: list[tuple[int, str]] = []
    for node in ast.walk(ast.parse(path.read_text(), str(path))):
        if isinstance(node, ast.Import):
            found += [(0, alias.name) for alias in node.names]
        elif isinstance(node, ast.ImportFrom):
            found.append((node.level, node.module or ""))
    return found


def test_only_grippers_lands_at_the_top_of_site_packages() -> None:
    config = tomllib.loads((ROOT / "pyproject.toml").read_text())["tool"]["setuptools"]
    assert config["packages"], "packages are listed explicitly"
    assert all(p == "grippers" or p.startswith("grippers.") for p in config["packages"]), config["packages"]
    assert config["package-dir"]["grippers.drivers"] == "drivers"
    assert "py.typed" in config["package-data"]["grippers"]
    assert (ROOT / "grippers" / "py.typed").exists()


def test_drivers_never_import_the_api_layer() -> None:
    """Drivers import each other relatively and never reach above their own package."""
    for path in sorted((ROOT / "drivers").rglob("*.py")):
        depth = len(path.relative_to(ROOT / "drivers").parts) - 1  # levels below drivers/
        for level, module in _imports(path):
            assert not (level == 0 and module.split(".")[0] in {"grippers", "drivers"}), (path, module)
            assert level <= depth + 1, f"{path} reaches above drivers/ ({'.' * level}{module})"


def test_sans_io_cores_import_no_io() -> None:
    for rel in SANS_IO:
        for level, module in _imports(ROOT / rel):
            if level == 0:
                assert module.split(".")[0] not in IO_MODULES, (rel, module)


def test_a_users_own_drivers_package_does_not_break_grippers(tmp_path: Path) -> None:
    """The failure users hit: a project with its own ``drivers/`` package next to its script."""
    (tmp_path / "drivers").mkdir()
    (tmp_path / "drivers" / "__init__.py").write_text("MINE = True\n")
    code = (
        "import drivers, grippers\n"
        "assert drivers.MINE\n"
        "with grippers.open('sim://wsg50') as g:\n"
        "    print(g.info().model)\n"
    )
    out = subprocess.run(
        [sys.executable, "-c", code], cwd=tmp_path, capture_output=True, text=True, timeout=60, check=False
    )
    assert out.returncode == 0, out.stderr
    assert out.stdout.strip() == "WSG 50"
