"""Issue 16 §6: `profiles show NAME` prints TOML that `profiles validate` accepts and that loads back to the
same profile, for every built-in profile."""

from __future__ import annotations

import tomllib
from pathlib import Path

import pytest

from grippers.cli import main
from grippers.cli.toml_out import dumps
from grippers.profiles import list_profiles, load_file, load_profile

BUILTINS = sorted(p.name for p in list_profiles())


@pytest.mark.parametrize("name", BUILTINS)
def test_show_round_trips(name: str, tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    assert main(["profiles", "show", name]) == 0
    text = capsys.readouterr().out
    path = tmp_path / f"{name}-copy.toml"
    path.write_text(text)
    assert main(["profiles", "validate", str(path)]) == 0
    assert capsys.readouterr().out.strip() == f"{path}: ok"
    original = load_profile(name).model_dump(mode="json")
    assert load_file(path).model_dump(mode="json") == original


def test_writer_spells_what_toml_needs() -> None:
    doc = {"a": 1.5, "b": float("inf"), "c": None, "name with space": 'x"y\n', "t": {"u": [1, 2], "v": True}}
    assert tomllib.loads(dumps(doc)) == {
        "a": 1.5,
        "b": float("inf"),
        "name with space": 'x"y\n',
        "t": {"u": [1, 2], "v": True},
    }
