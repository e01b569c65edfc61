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


def test_the_error_is_one_short_line_naming_the_top_file(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    # Issue 33 §3: every level prefixed its own file ("a.toml: extends 'b': b.toml: extends 'c': ..."), so a
    # chain of 20 gave an error of 870 characters.
    _chain(tmp_path, MAX_EXTENDS_DEPTH + 4)
    monkeypatch.setenv("GRIPPERS_PROFILE_PATH", str(tmp_path))
    with pytest.raises(ProfileError) as caught:
        load_profile(f"deep{MAX_EXTENDS_DEPTH + 3}")
    message = str(caught.value)
    assert message.startswith(str(tmp_path / f"deep{MAX_EXTENDS_DEPTH + 3}.toml"))
    assert message.count(".toml") == 2 and "\n" not in message and len(message) < 250, message
    assert f"at most {MAX_EXTENDS_DEPTH}" in message


def test_the_cap_is_exact_and_documented(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    # deepN stands on N + 1 levels of extends (deep0 extends wsg50): the cap's level loads, one more does not.
    _chain(tmp_path, MAX_EXTENDS_DEPTH + 1)
    monkeypatch.setenv("GRIPPERS_PROFILE_PATH", str(tmp_path))
    assert load_profile(f"deep{MAX_EXTENDS_DEPTH - 1}").name == f"deep{MAX_EXTENDS_DEPTH - 1}"
    with pytest.raises(ProfileError, match=f"more than {MAX_EXTENDS_DEPTH} levels"):
        load_profile(f"deep{MAX_EXTENDS_DEPTH}")
    doc = (Path(__file__).resolve().parents[2] / "docs" / "profiles.md").read_text(encoding="utf-8")
    assert "as long as you like" not in doc and f"up to {MAX_EXTENDS_DEPTH} levels" in doc
