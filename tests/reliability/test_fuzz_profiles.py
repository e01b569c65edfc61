"""Fuzzing the profile loader: malformed files give a ProfileError that names the file and the field.

tests/api/test_profiles.py has hand-picked malformed files; here every field of a shipped WSG and MSG
profile is deleted, retyped, or joined by an unknown key, and random bytes are read as TOML and JSON.
"""

from __future__ import annotations

import atexit
import copy
import json
import shutil
import tempfile
import tomllib
from pathlib import Path
from typing import Any

import pytest
from hypothesis import given
from hypothesis import strategies as st

from grippers.errors import ProfileError
from grippers.profiles import ProfileBase, load_file

ROOT = Path(__file__).resolve().parents[2]
BASES = {n: tomllib.loads((ROOT / "profiles" / f"{n}.toml").read_text()) for n in ("wsg50", "msg-150")}
_TMP = tempfile.mkdtemp(prefix="grippers-profile-fuzz-")
atexit.register(shutil.rmtree, _TMP, True)


def _paths(data: dict[str, Any], prefix: tuple[str, ...] = ()) -> list[tuple[str, ...]]:
    out = []
    for key, value in data.items():
        out.append(prefix + (key,))
        if isinstance(value, dict):
            out += _paths(value, prefix + (key,))
    return out


def _get(data: Any, path: tuple[str, ...]) -> Any:
    for key in path:
        data = data[key]
    return data


PATHS = {name: _paths(base) for name, base in BASES.items()}
TABLES = {name: [()] + [p for p in PATHS[name] if isinstance(_get(BASES[name], p), dict)] for name in BASES}


def _wrong_value(current: Any, pick: int) -> Any:
    """A value of a kind the field cannot take (never a coercible one)."""
    if isinstance(current, bool):
        choices: list[Any] = [{"x": 1}, [1], "maybe"]
    elif isinstance(current, int | float):
        choices = [{"x": 1}, [1], "not a number"]
    elif isinstance(current, str):
        choices = [{"x": 1}, [1], 3.5]
    elif isinstance(current, list):
        choices = [{"x": 1}, 3.5, "text"]
    else:  # a table
        choices = [3.5, "text", [1]]
    return choices[pick % len(choices)]


def _write(text: str | bytes, suffix: str) -> Path:
    path = Path(tempfile.mktemp(suffix=suffix, dir=_TMP))
    path.write_bytes(text if isinstance(text, bytes) else text.encode())
    return path


def _load(data: dict[str, Any]) -> tuple[Path, ProfileBase | ProfileError]:
    path = _write(json.dumps(data), ".json")
    try:
        return path, load_file(path)
    except ProfileError as exc:
        return path, exc
    finally:
        path.unlink()


@given(
    base=st.sampled_from(sorted(BASES)), data=st.data(), how=st.sampled_from(["delete", "retype", "extra"])
)
def test_fuzz_profile_mutations_name_the_field(base: str, data: st.DataObject, how: str, fuzz_count) -> None:
    fuzz_count["profile loader: mutated fields"] += 1
    profile = copy.deepcopy(BASES[base])
    if how == "extra":
        table = data.draw(st.sampled_from(TABLES[base]))
        key = data.draw(st.from_regex(r"[a-z][a-z_]{0,10}", fullmatch=True))
        target = _get(profile, table)
        if key in target:
            return
        target[key] = 1
        path = table + (key,)
    else:
        path = data.draw(st.sampled_from(PATHS[base]))
        parent = _get(profile, path[:-1])
        if how == "delete":
            del parent[path[-1]]
        else:
            parent[path[-1]] = _wrong_value(parent[path[-1]], data.draw(st.integers(0, 2)))
    file, result = _load(profile)
    if how == "delete" and isinstance(result, ProfileBase):
        return  # an optional field: its default applies
    assert isinstance(result, ProfileError), f"{how} {path} was accepted"
    message = str(result)
    assert str(file) in message
    assert ".".join(path) in message, message


@given(text=st.text(max_size=300) | st.binary(max_size=300), suffix=st.sampled_from([".toml", ".json"]))
def test_fuzz_profile_loader_random_files(text: str | bytes, suffix: str, fuzz_count) -> None:
    """Random bytes as a profile file: a ProfileError naming the file, never another exception."""
    fuzz_count["profile loader: random files"] += 1
    path = _write(text, suffix)
    try:
        with pytest.raises(ProfileError) as info:
            load_file(path)
        assert str(path) in str(info.value)
    finally:
        path.unlink()


@pytest.mark.parametrize("text", ["[1, 2]", '"wsg50"', "3"])
def test_json_profile_that_is_not_an_object_is_a_profile_error(text: str) -> None:
    path = _write(text, ".json")
    try:
        with pytest.raises(ProfileError):
            load_file(path)
    finally:
        path.unlink()
