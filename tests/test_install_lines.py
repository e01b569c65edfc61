"""Issue 31 §1: every ``pip install`` line in the README and docs/ names a form that works.

docs/ros2.md, docs/remote.md and docs/troubleshooting.md said ``pip install grippers``: no package index
serves it, so a new user's first command failed. What works: a checkout (``.``, ``-e .``, a path, with or
without extras), a wheel built from it, an extra added to the grippers already installed
(``'grippers[plot]'``: pip takes grippers as satisfied and fetches only the extra's packages), and the
third-party packages grippers depends on. The second test runs those forms for real in a fresh virtual
environment, with ``--no-index``: nothing comes from an index.
"""

from __future__ import annotations

import re
import shlex
import shutil
import subprocess
import sys
import tomllib
import venv
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
DOCS = [ROOT / "README.md", *sorted((ROOT / "docs").glob("*.md"))]
PIP = re.compile(r"pip install\s+((?:[^`\n#;&|)]|'[^'\n]*')+)")
PROJECT = tomllib.loads((ROOT / "pyproject.toml").read_text())["project"]
EXTRAS = set(PROJECT["optional-dependencies"])
REQUIREMENT = re.compile(r"^([A-Za-z0-9._-]+)(\[[^\]]*\])?")
# The packages grippers depends on (or an extra brings), by name: installing one of those from an index works.
THIRD_PARTY = {
    REQUIREMENT.match(r).group(1).lower()  # type: ignore[union-attr]
    for r in PROJECT["dependencies"] + [r for rs in PROJECT["optional-dependencies"].values() for r in rs]
}


def _install_lines() -> list[tuple[str, str, bool]]:
    """(where, arguments, whether the docs tell the reader to run it) of every ``pip install`` line."""
    found = []
    for path in DOCS:
        text = path.read_text(encoding="utf-8")
        for match in PIP.finditer(text):
            where = f"{path.relative_to(ROOT)}: pip install {match.group(1).strip()}"
            found.append((where, match.group(1), _is_command(text, match.start())))
    return found


def _is_command(text: str, start: int) -> bool:
    """A line the reader runs (it opens a code span or a code line: `` `pip install …` ``), not a program's
    message quoted (``fix: pip install …``, printed by a grippers already installed)."""
    before = text[:start].rstrip(" $")
    return before == "" or before.endswith(("`", "\n"))


def _problem(args: str, command: bool = True) -> str | None:
    """Why ``pip install ARGS`` would fail on a machine with no index serving grippers, or None.

    ``command``: the docs tell the reader to run it, maybe before grippers is installed (issue 39 §4: a
    reader of a page ran ``pip install 'grippers[plot]'`` in a fresh environment, which no index serves); a
    program's quoted message (``command`` False) is printed by an installed grippers, to which pip adds the
    extra's packages."""
    try:
        words = shlex.split(args)
    except ValueError:
        return "unbalanced quotes"
    targets = [w for w in words if not w.startswith("-")]
    if not targets:
        return "installs nothing"
    for target in targets:
        if target.startswith((".", "/", "~")) or target.split("[")[0].endswith(".whl"):
            continue  # a checkout, a path or a wheel, with or without extras
        req = REQUIREMENT.match(target)
        if req is None:
            return f"{target!r} is not a requirement"
        name, extras = req.group(1).lower(), req.group(2)
        if name == "grippers":
            if not extras:
                return "no package index serves grippers: install the checkout (.) or a wheel built from it"
            unknown = set(extras.strip("[]").split(",")) - EXTRAS
            if unknown:
                return f"grippers has no extra {sorted(unknown)} (extras: {sorted(EXTRAS)})"
            if command:
                return f"no package index serves grippers: in the checkout, pip install -e '.{extras}'"
            continue  # a message of an installed grippers: the extra is added to it
        if name not in THIRD_PARTY:
            return f"{name} is not a dependency of grippers"
    return None


def test_the_docs_have_install_lines() -> None:
    lines = [where for where, _, _ in _install_lines()]
    assert len(lines) >= 10
    for doc in ("docs/ros2.md", "docs/remote.md", "docs/troubleshooting.md", "README.md"):
        assert any(where.startswith(doc) for where in lines), doc


@pytest.mark.parametrize(
    ("where", "args", "command"), _install_lines(), ids=[w for w, _, _ in _install_lines()]
)
def test_every_install_line_names_a_form_that_works(where: str, args: str, command: bool) -> None:
    problem = _problem(args, command)
    assert problem is None, f"{where}: {problem}"


def test_the_check_refuses_what_failed() -> None:
    assert _problem("grippers") is not None
    assert _problem("'grippers[nosuch]'") is not None
    assert _problem("-e '.[test]'") is None
    assert _problem("'grippers[plot]'") is not None  # run from a page before grippers is installed
    assert _problem("'grippers[plot]'", command=False) is None  # a message of the installed grippers
    assert _problem("-e '.[plot]'") is None
    text = "MCAP (`pip install 'grippers[record]'`), or: fix: pip install 'grippers[yaml]'"
    assert [_is_command(text, m.start()) for m in PIP.finditer(text)] == [True, False]
    assert _problem("dist/grippers-0.1.0-py3-none-any.whl") is None


@pytest.mark.timeout(300)
def test_the_wheel_installs_in_a_fresh_environment_without_an_index(tmp_path: Path) -> None:
    """A wheel built from (a copy of) the checkout, installed with --no-index into a new virtual environment
    that sees this environment's packages as its dependencies (a .pth file); then an extra, the docs' way."""
    source = tmp_path / "checkout"  # built from a copy: the build leaves build/ and egg-info behind
    tracked = subprocess.check_output(["git", "ls-files", "-z"], cwd=ROOT, text=True).split("\0")
    for name in filter(None, tracked):
        if (ROOT / name).is_file():
            (source / name).parent.mkdir(parents=True, exist_ok=True)
            shutil.copy2(ROOT / name, source / name)
    dist = tmp_path / "dist"
    build = subprocess.run(
        [sys.executable, "-m", "pip", "wheel", "-q", "--no-deps", "-w", str(dist), str(source)],
        capture_output=True,
        text=True,
        timeout=240,
    )
    if build.returncode != 0:  # building fetches setuptools and wheel: no registry reachable here
        pytest.skip(f"cannot build the wheel here: {build.stderr.strip()[-300:]}")
    (wheel,) = dist.glob("grippers-*.whl")
    env = tmp_path / "env"
    venv.EnvBuilder(with_pip=True).create(env)
    python = env / "bin" / "python"
    site = Path(
        subprocess.check_output(
            [str(python), "-c", "import sysconfig; print(sysconfig.get_paths()['purelib'])"], text=True
        ).strip()
    )
    ours = Path(
        subprocess.check_output(
            [sys.executable, "-c", "import sysconfig; print(sysconfig.get_paths()['purelib'])"], text=True
        ).strip()
    )
    (site / "deps.pth").write_text(f"{ours}\n")

    def pip(*args: str) -> subprocess.CompletedProcess[str]:
        return subprocess.run(
            [str(python), "-m", "pip", "install", "-q", "--no-index", *args],
            capture_output=True,
            text=True,
            timeout=120,
        )

    installed = pip("--force-reinstall", "--no-deps", str(wheel))
    assert installed.returncode == 0, installed.stderr
    where = subprocess.run(
        [str(python), "-c", "import grippers, grippers.drivers.urls; print(grippers.__file__)"],
        capture_output=True,
        text=True,
        timeout=60,
        cwd=tmp_path,
    )
    assert where.returncode == 0, where.stderr
    assert Path(where.stdout.strip()).is_relative_to(site), where.stdout
    extra = pip("grippers[plot]")  # the docs' form for an extra: grippers is satisfied, matplotlib is there
    assert extra.returncode == 0, extra.stderr
    cli = subprocess.run(
        [str(env / "bin" / "grippers"), "--version"], capture_output=True, text=True, timeout=60
    )
    assert cli.returncode == 0 and "grippers" in cli.stdout, cli.stdout + cli.stderr
