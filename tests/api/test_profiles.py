"""Profiles: shipped ones validate, user files shadow them, a bad file names the file, field and rule."""

from __future__ import annotations

import json
from pathlib import Path

import pytest

from grippers import ProfileError
from grippers import profiles as p

from .conftest import SHIPPED


def test_shipped_profiles_load_with_both_families() -> None:
    names = {x.name for x in p.list_profiles()}
    assert set(SHIPPED) <= names
    assert {"wsg25", "wsg32", "wsg50", "wsg70", "msg-100", "msg-150", "msg-200"} <= names
    assert p.load_profile("WSG 50").name == "wsg50"
    assert p.load_profile("msg150").name == "msg-150"


@pytest.mark.parametrize("name", SHIPPED)
def test_limits_are_si_and_ordered(name: str) -> None:
    limits = p.load_profile(name).limits()
    assert 0 <= limits.min_width < limits.max_width < 0.5  # metres
    assert 0 < limits.min_speed < limits.max_speed < 1.0  # m/s
    assert 0 < limits.min_force < limits.max_force


def test_msg_current_limit_comes_from_safety() -> None:
    msg = p.load_profile("msg-150")
    assert isinstance(msg, p.MsgProfile)
    assert msg.effective_max_current_ma == 1000
    assert msg.limits().max_current == pytest.approx(1.0)


def _write(tmp_path: Path, name: str, text: str) -> Path:
    path = tmp_path / name
    path.write_text(text)
    return path


def test_validation_error_names_file_field_and_rule(tmp_path: Path) -> None:
    src = (Path(p.__file__).parents[1] / "profiles" / "wsg50.toml").read_text()
    bad = _write(tmp_path, "bad.toml", src.replace("stroke_mm = 110.0", "stroke_mm = -3"))
    with pytest.raises(ProfileError) as err:
        p.load_file(bad)
    message = str(err.value)
    assert "bad.toml" in message and "mechanics.stroke_mm" in message and "greater than 0" in message
    assert p.validate_file(bad) == [message]


@pytest.mark.parametrize(
    ("text", "expected"),
    [
        ('family = "wsg"\nname = "x"', "vendor"),  # missing fields
        ('family = "acme"\nname = "x"', "unknown family"),
        ("this is not toml", "not valid TOML"),
        ('family = "wsg"\nname = "Bad Name"', "name"),
    ],
)
def test_malformed_files_are_refused(tmp_path: Path, text: str, expected: str) -> None:
    path = _write(tmp_path, "x.toml", text)
    with pytest.raises(ProfileError, match=expected):
        p.load_file(path)


def test_typo_in_a_field_is_refused(tmp_path: Path) -> None:
    src = (Path(p.__file__).parents[1] / "profiles" / "msg-150.toml").read_text()
    path = _write(tmp_path, "typo.toml", src.replace("grasp_travel_mm", "grasp_travle_mm"))
    with pytest.raises(ProfileError, match="grasp_travle_mm"):
        p.load_file(path)


def test_search_path_user_file_shadows_builtin(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    src = (Path(p.__file__).parents[1] / "profiles" / "wsg50.toml").read_text()
    _write(tmp_path, "wsg50.toml", src.replace("default_force_n = 40.0", "default_force_n = 33.0"))
    monkeypatch.setenv("GRIPPERS_PROFILE_PATH", str(tmp_path))
    assert p.load_profile("wsg50").mechanics.default_force_n == 33.0
    monkeypatch.setenv("GRIPPERS_PROFILE_PATH", "")
    monkeypatch.setenv("XDG_CONFIG_HOME", str(tmp_path / "none"))
    assert p.load_profile("wsg50").mechanics.default_force_n == 40.0


def test_unknown_profile_lists_known_names() -> None:
    with pytest.raises(ProfileError, match="wsg50"):
        p.load_profile("wsg99")


def test_json_schema_covers_every_installed_family() -> None:
    schema = p.json_schema()
    text = json.dumps(schema)
    assert "WsgProfile" in text and "MsgProfile" in text and "RobotiqProfile" in text


def test_the_backend_declares_the_profile_model() -> None:
    """Issue 28 §2: no table in profiles.py; the family's backend says which model validates its profiles, and
    ``profile_model = None`` means the generic ProfileBase (it used to raise "unknown family")."""
    from grippers.backends import find_backend

    assert not hasattr(p, "BUILTIN_PROFILE_MODELS")
    for family in ("wsg", "stepfoc", "robotiq"):
        assert p._profile_model(family) is find_backend(family).profile_model
    assert p._profile_model("zenoh") is p.ProfileBase  # the zenoh backend declares None
    with pytest.raises(ValueError, match="unknown family 'acme'"):
        p._profile_model("acme")
