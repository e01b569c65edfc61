"""The ``gripper_sim`` fixture of grippers.testing, as a user's suite gets it (issue 20 §3)."""

from __future__ import annotations

import subprocess
import sys
import textwrap
from pathlib import Path

import pytest

import grippers
from grippers import URLError
from grippers.testing import GripperSims

BUILTIN = sorted(p.stem for p in (Path(__file__).parents[2] / "profiles").glob("*.toml"))


@pytest.mark.parametrize("profile", BUILTIN)
def test_every_builtin_profile_is_simulated(gripper_sim: GripperSims, profile: str) -> None:
    stroke = grippers.load_profile(profile).mechanics.stroke_mm
    part = round(stroke * 0.3, 1)
    url = gripper_sim(profile, part_width_mm=part, time_scale=50)
    with grippers.open(url) as g:
        assert g.profile.name == profile  # the URL carries the profile: an MSG cannot report its rail
        g.home()
        result = g.grasp(part / 1000, force=g.limits.max_force / 2)
        assert result.grasped and result.width == pytest.approx(part / 1000, abs=0.003)
    assert url.simulator.model is not None


def test_a_misspelt_setting_is_refused(gripper_sim: GripperSims) -> None:
    with pytest.raises(URLError, match="part_widht_mm"):
        gripper_sim("wsg50", part_widht_mm=40)


def test_a_dead_simulator_thread_fails_the_test() -> None:
    sims = GripperSims()
    url = sims("wsg50")
    url.simulator.error = RuntimeError("boom")  # what the simulator's thread records when it dies
    assert sims.close() == [f"{url.simulator.url}: simulator thread died: RuntimeError('boom')"]


def test_a_users_suite_gets_the_fixture_from_the_installed_plugin(tmp_path: Path) -> None:
    """Through the pytest11 entry point, in a fresh interpreter, with no conftest of ours."""
    (tmp_path / "test_user.py").write_text(
        textwrap.dedent(
            """
            import grippers

            def test_pick(gripper_sim):
                url = gripper_sim("wsg50", part_width_mm=40, time_scale=50)
                with grippers.open(url) as g:
                    g.home()
                    assert g.grasp(0.04).grasped
            """
        )
    )
    done = subprocess.run(
        [sys.executable, "-m", "pytest", "-q", "-p", "no:cacheprovider", str(tmp_path)],
        cwd=tmp_path,
        capture_output=True,
        text=True,
        timeout=120,
    )
    assert done.returncode == 0, done.stdout + done.stderr
    assert "1 passed" in done.stdout
