"""Issue 16 §6: the plugin of docs/backends.md is complete. Its two files are copied out of the page,
installed with pip (a real distribution with its entry point), and `grippers info` and `grippers probe` run on
it; their output must be what the page shows."""

from __future__ import annotations

import os
import re
import subprocess
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[2]
PAGE = ROOT / "docs" / "backends.md"


def _block(text: str, lang: str, first_line: str) -> str:
    m = re.search(rf"```{lang}\n({re.escape(first_line)}\n.*?)```", text, re.S)
    assert m, f"no ```{lang} block starting {first_line!r} in {PAGE}"
    return m.group(1)


def _sessions(text: str) -> dict[str, str]:
    """``$ command`` lines of the page's plain blocks and the output printed under each."""
    out: dict[str, str] = {}
    blocks, current, lang = [], None, ""
    for line in text.splitlines():
        if line.startswith("```"):
            if current is None:
                current, lang = [], line[3:].strip()
            else:
                if not lang:
                    blocks.append("\n".join(current))
                current = None
        elif current is not None:
            current.append(line)
    for block in blocks:
        command = None
        for line in block.splitlines():
            if line.startswith("$ "):
                command = line[2:]
                out[command] = ""
            elif command is not None:
                out[command] += line + "\n"
    return out


@pytest.fixture(scope="module")
def plugin_site(tmp_path_factory: pytest.TempPathFactory) -> Path:
    text = PAGE.read_text()
    src = tmp_path_factory.mktemp("acme-src")
    (src / "acme_grippers.py").write_text(_block(text, "python", "# acme_grippers.py"))
    (src / "pyproject.toml").write_text(_block(text, "toml", "# pyproject.toml of the plugin"))
    site = tmp_path_factory.mktemp("acme-site")
    proc = subprocess.run(
        [sys.executable, "-m", "pip", "install", "-q", "--no-deps", "--target", str(site), str(src)],
        capture_output=True,
        text=True,
        timeout=300,
    )
    if proc.returncode != 0 and "setuptools" in proc.stderr and "No matching distribution" in proc.stderr:
        pytest.skip("pip cannot fetch setuptools to build the plugin here (offline without a wheel cache)")
    assert proc.returncode == 0, proc.stderr[-2000:]
    assert list(site.glob("acme_grippers-*.dist-info/entry_points.txt")), "no entry point installed"
    return site


def _grippers(site: Path, *args: str) -> subprocess.CompletedProcess:
    env = {**os.environ, "PYTHONPATH": str(site)}
    return subprocess.run(
        [sys.executable, "-m", "grippers", *args],
        capture_output=True,
        text=True,
        timeout=60,
        cwd=ROOT,
        env=env,
    )


@pytest.mark.parametrize("command", ["info acme+tcp://10.0.0.5", "probe acme+tcp://10.0.0.5"])
def test_plugin_commands_print_what_the_page_shows(plugin_site: Path, command: str) -> None:
    expected = _sessions(PAGE.read_text())[f"grippers {command}"]
    r = _grippers(plugin_site, *command.split())
    assert r.returncode == 0, r.stderr
    assert r.stdout == expected


def test_plugin_gripper_moves_with_limit_checks(plugin_site: Path) -> None:
    r = _grippers(plugin_site, "grasp", "acme+tcp://10.0.0.5", "30", "--force", "20", "--home", "--json")
    assert r.returncode == 0, r.stderr
    assert '"grasped": true' in r.stdout
    over = _grippers(plugin_site, "move", "acme+tcp://10.0.0.5", "500", "--home")
    assert over.returncode == 2 and "outside" in over.stderr


# -- issue 28 §2: a plugin's own profile folder and profile model, found once it is installed ----------------
#
# An installed-like plugin without pip: a package and a ``*.dist-info`` with its entry points, on sys.path (a
# subprocess's PYTHONPATH, or this process's sys.path), which is all importlib.metadata reads. Its family
# ``acme`` reuses the Robotiq driver and simulator (a lab's rebadged 2F-85), and declares its own profile
# model and its profile folder in the entry-point group ``grippers.profiles``.

ACME_PLUGIN = """
from typing import Literal

from grippers.backends.robotiq import RobotiqBackend, RobotiqProfile
from grippers.kit import CommandHooks


class AcmeProfile(RobotiqProfile):
    family: Literal["acme"] = "acme"  # type: ignore[assignment]


class AcmeBackend(RobotiqBackend):
    family = "acme"
    profile_model = AcmeProfile
    commands = CommandHooks()  # the defaults: `grippers sim acme` simulates the first acme profile found

    def simulator(self, profile, settings, listen=None):
        server = super().simulator(profile, settings, listen)
        server.url = server.url.replace("robotiq+", "acme+", 1)
        return server
"""

ACME_PROFILE = """
name = "acme-a1"
aliases = ["Acme A1"]
family = "acme"
vendor = "Acme"
model = "A1"
url = "acme+tcp://127.0.0.1:5020"

[mechanics]
stroke_mm = 85.0
min_speed_mm_s = 20.0
max_speed_mm_s = 150.0
default_speed_mm_s = 100.0
min_force_n = 20.0
max_force_n = 235.0
default_force_n = 100.0

[robotiq]
open_count = 3
closed_count = 230
open_width_mm = 85.0
closed_width_mm = 0.0
"""


@pytest.fixture(scope="module")
def acme_site(tmp_path_factory: pytest.TempPathFactory) -> Path:
    site = tmp_path_factory.mktemp("acme-plugin-site")
    package = site / "acme_lab"
    (package / "profiles").mkdir(parents=True)
    (package / "__init__.py").write_text(ACME_PLUGIN)
    (package / "profiles" / "__init__.py").write_text("")
    (package / "profiles" / "acme-a1.toml").write_text(ACME_PROFILE)
    dist = site / "acme_lab-1.0.dist-info"
    dist.mkdir()
    (dist / "METADATA").write_text("Metadata-Version: 2.1\nName: acme-lab\nVersion: 1.0\n")
    (dist / "entry_points.txt").write_text(
        "[grippers.backends]\nacme = acme_lab:AcmeBackend\n\n[grippers.profiles]\nacme = acme_lab.profiles\n"
    )
    return site


def test_a_plugin_profile_is_found_by_name_without_the_profile_path(acme_site: Path) -> None:
    env_path = os.environ.get("GRIPPERS_PROFILE_PATH")
    assert not env_path, "the test must not lean on GRIPPERS_PROFILE_PATH"
    listed = _grippers(acme_site, "profiles", "list")
    assert listed.returncode == 0, listed.stderr
    assert "acme-a1" in listed.stdout and "wsg50" in listed.stdout
    path = _grippers(acme_site, "profiles", "path")
    assert str(acme_site / "acme_lab" / "profiles") in path.stdout
    state = _grippers(acme_site, "state", "sim://acme-a1?activated=true", "--json")
    assert state.returncode == 0, state.stderr
    assert '"width_mm": 85.0' in state.stdout
    probe = _grippers(acme_site, "probe", "sim://acme-a1?activated=true")
    assert probe.returncode == 0, probe.stdout + probe.stderr
    assert "acme-a1" in probe.stdout
    schema = _grippers(acme_site, "profiles", "schema")
    assert schema.returncode == 0 and "AcmeProfile" in schema.stdout  # the union of the installed families


def test_gripper_sim_starts_a_plugin_profile_by_name(
    acme_site: Path, monkeypatch: pytest.MonkeyPatch, gripper_sim
) -> None:
    import grippers

    monkeypatch.syspath_prepend(str(acme_site))
    url = gripper_sim("acme-a1", activated=True)
    assert url.startswith("acme+tcp://")
    with grippers.open(url) as g:
        assert g.profile.name == "acme-a1" and type(g.profile).__name__ == "AcmeProfile"
        assert g.limits.max_width == pytest.approx(0.085)


def test_grippers_sim_serves_a_plugin_family_by_its_hooks(acme_site: Path) -> None:
    """``grippers sim acme``: the plugin declares no sim command of its own, so its ``simulator`` gets the
    common options, and its default profile is the first of its family on the search path."""
    import json

    env = {**os.environ, "PYTHONPATH": str(acme_site), "PYTHONUNBUFFERED": "1"}
    cmd = [sys.executable, "-m", "grippers", "sim", "acme", "--listen", "tcp://127.0.0.1:0", "--json"]
    proc = subprocess.Popen(cmd, cwd=ROOT, env=env, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    try:
        assert proc.stdout is not None
        line = proc.stdout.readline()
        assert line, proc.stderr.read() if proc.stderr else ""
        doc = json.loads(line)
        assert doc["urls"][0].startswith("acme+tcp://127.0.0.1:") and doc["what"] == "simulated A1"
    finally:
        proc.terminate()
        proc.wait(10)
        for stream in (proc.stdout, proc.stderr):
            if stream:
                stream.close()
