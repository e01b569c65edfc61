"""Fuzzing the profile loader: malformed files give a ProfileError that names the file and the field.

tests/api/test_profiles.py has hand-picked malformed files; here every field of a shipped WSG and MSG
profile is deleted, retyped, or joined by an unknown key, and random bytes are read as TOML and JSON.
"""

from __future__ import annotations

import atexit
import copy
import json
import math
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


NUMBERS = {
    name: [
        p
        for p in PATHS[name]
        if isinstance(_get(BASES[name], p), int | float) and not isinstance(_get(BASES[name], p), bool)
    ]
    for name in BASES
}
EXTREME = st.sampled_from(
    [float("inf"), float("-inf"), float("nan"), 1e308, -1e308, 1e-300, 0.0, -1.0, 2**63]
)


@given(
    base=st.sampled_from(sorted(BASES)),
    data=st.data(),
    value=EXTREME | st.floats(allow_nan=True, allow_infinity=True) | st.integers(-(2**70), 2**70),
)
def test_fuzz_profile_numbers_load_only_when_they_can_work(
    base: str, data: st.DataObject, value: float, fuzz_count
) -> None:
    """Any number in any numeric field (issue 13 item 6): either a ProfileError naming a field, or a profile
    whose limits are finite and non-empty, so every check has something to allow and every wait is finite."""
    fuzz_count["profile loader: numbers"] += 1
    profile = copy.deepcopy(BASES[base])
    path = data.draw(st.sampled_from(NUMBERS[base]))
    _get(profile, path[:-1])[path[-1]] = value
    file, result = _load(profile)
    if isinstance(result, ProfileError):
        assert str(file) in str(result)
        return
    limits = result.limits()
    numbers = [
        limits.min_width,
        limits.max_width,
        limits.min_speed,
        limits.max_speed,
        limits.min_force,
        limits.max_force,
    ]
    assert all(math.isfinite(n) for n in numbers), (path, value, limits)
    assert limits.min_width < limits.max_width <= 10.0, (path, value, limits)
    assert limits.min_speed <= limits.max_speed and limits.max_speed > 0, (path, value, limits)
    assert limits.min_force <= limits.max_force, (path, value, limits)
    timeout = result.transport.timeout_s  # type: ignore[attr-defined]
    assert 0 < timeout <= 3600, (path, value)
    maps = getattr(result, "maps", None)
    if maps is not None:  # the MSG's force comes from its current: some current must give a legal force
        npa, top = maps.newton_per_amp, result.effective_max_current_ma  # type: ignore[attr-defined]
        reachable = (maps.min_current_ma / 1000 * npa, top / 1000 * npa)
        assert max(limits.min_force, reachable[0]) <= min(limits.max_force, reachable[1])
        assert maps.closed_width_mm / 1000 <= limits.min_width + 1e-9
        assert maps.open_width_mm / 1000 >= limits.max_width - 1e-9


def _extends_chain(tmp: Path, names: list[str], bases: list[str]) -> None:
    for name, base in zip(names, bases, strict=True):
        (tmp / f"{name}.toml").write_text(f'name = "{name}"\nextends = "{base}"\n', encoding="utf-8")


@given(
    edges=st.lists(st.integers(0, 5), min_size=1, max_size=6),
)
def test_fuzz_profile_extends_graphs_end_or_are_refused(edges: list[int], fuzz_count) -> None:
    """Random ``extends`` graphs among six user files (some ending at a built-in): every lookup ends, with
    a profile or a ProfileError (a cycle, an unknown base), never a RecursionError or a hang."""
    import os

    from grippers.profiles import load_profile

    fuzz_count["profile loader: extends graphs"] += 1
    tmp = Path(tempfile.mkdtemp(dir=_TMP))
    names = [f"p{i}" for i in range(len(edges))]
    bases = [f"p{e}" if e < len(edges) else "wsg50" for e in edges]
    _extends_chain(tmp, names, bases)
    old = os.environ.get("GRIPPERS_PROFILE_PATH")
    os.environ["GRIPPERS_PROFILE_PATH"] = str(tmp)
    try:
        for name in names:
            try:
                profile = load_profile(name)
            except ProfileError as exc:
                assert "cycle" in str(exc) or "no profile named" in str(exc), exc
            else:
                assert profile.name == name and profile.mechanics.stroke_mm == 110.0
    finally:
        if old is None:
            os.environ.pop("GRIPPERS_PROFILE_PATH", None)
        else:
            os.environ["GRIPPERS_PROFILE_PATH"] = old
        shutil.rmtree(tmp, True)
