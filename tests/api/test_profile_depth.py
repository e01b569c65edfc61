"""Deep ``extends`` chains are refused by name, quickly (issue 23 §3: 300 levels took over 120 s)."""

from __future__ import annotations

from pathlib import Path

import pytest

from grippers.errors import ProfileError
from grippers.profiles import MAX_EXTENDS_DEPTH, list_profiles, load_profile


def _chain(tmp_path: Path, levels: int) -> None:
    (tmp_path / "deep0.toml").write_text('name = "deep0"\nextends = "wsg50"\n')
    for i in range(1, levels):
        (tmp_path / f"deep{i}.toml").write_text(f'name = "deep{i}"\nextends = "deep{i - 1}"\n')


def test_a_chain_within_the_cap_loads(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    _chain(tmp_path, MAX_EXTENDS_DEPTH - 1)
    monkeypatch.setenv("GRIPPERS_PROFILE_PATH", str(tmp_path))
    profile = load_profile(f"deep{MAX_EXTENDS_DEPTH - 2}")
    assert profile.model == load_profile("wsg50").model


def test_a_deeper_chain_is_a_profile_error(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    _chain(tmp_path, 300)
    monkeypatch.setenv("GRIPPERS_PROFILE_PATH", str(tmp_path))
    with pytest.raises(ProfileError, match=f"more than {MAX_EXTENDS_DEPTH} levels of extends"):
        load_profile("deep299")
    # Listing visits every file of the chain; each one ends at the cap instead of walking 300 levels.
    names = {p.name for p in list_profiles()}
    assert "wsg50" in names
