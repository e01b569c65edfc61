"""Issue 28 §3: a ``zenoh://`` client needs no vendor code. The served profile is re-validated with the
family's model when it is installed here, and read as the generic profile (identity, mechanics, limits) when
it is not, instead of refusing the gripper with "unknown family"."""

from __future__ import annotations

import pytest

import grippers
import grippers.backends
from grippers import profiles
from grippers.profiles import GenericProfile

from .conftest import ServeProcess, sim

pytestmark = pytest.mark.timeout(60)


def test_a_client_without_the_family_reads_the_served_profile_as_generic(
    monkeypatch: pytest.MonkeyPatch,
) -> None:
    server = ServeProcess(f"hand={sim('robotiq-2f85')}")
    try:
        real = grippers.backends.find_backend
        # This process has no robotiq plugin: its backend (and so its profile model) is not found here.
        monkeypatch.setattr(grippers.backends, "find_backend", lambda f: None if f == "robotiq" else real(f))
        with pytest.raises(ValueError, match="unknown family 'robotiq'"):
            profiles._profile_model("robotiq")
        with grippers.open(server.urls["hand"]) as g:
            assert isinstance(g.profile, GenericProfile)
            assert g.profile.name == "robotiq-2f85" and g.profile.family == "robotiq"
            assert g.profile.mechanics.max_width_mm == pytest.approx(85.0)
            assert g.limits.max_width == pytest.approx(0.085)
            assert g.state().width == pytest.approx(0.085, abs=0.002)
    finally:
        server.close()


def test_generic_reading_drops_the_family_sections_and_still_checks_the_rest() -> None:
    data = {
        "name": "nosuchvendor-x",
        "family": "nosuchvendor",
        "vendor": "Acme",
        "model": "X",
        "url": "nosuchvendor+tcp://127.0.0.1",
        "mechanics": {
            "stroke_mm": 40,
            "min_speed_mm_s": 1,
            "max_speed_mm_s": 50,
            "default_speed_mm_s": 20,
            "min_force_n": 5,
            "max_force_n": 40,
            "default_force_n": 20,
        },
        "nosuchvendor": {"registers": 12},
    }
    with pytest.raises(grippers.ProfileError, match="unknown family"):
        profiles.parse_profile(data)  # a profile file of an uninstalled family is still refused
    profile = profiles.parse_profile(data, "served", generic=True)
    assert isinstance(profile, GenericProfile) and profile.limits().max_force == 40
    bad = {**data, "mechanics": {**data["mechanics"], "stroke_mm": -1}}
    with pytest.raises(grippers.ProfileError, match="stroke_mm"):
        profiles.parse_profile(bad, "served", generic=True)
