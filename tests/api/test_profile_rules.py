"""Profiles refuse what cannot work, the first match on the search path wins, files are parsed once, and a
profile may extend another (issues 13 items 6, 8, 9 and 16 §6). Each test failed on the code before."""

from __future__ import annotations

import os
from pathlib import Path

import pytest

import grippers
from grippers import LimitError, ProfileError
from grippers import profiles as p

from .conftest import ROOT, TIME_SCALE


@pytest.fixture(autouse=True)
def _own_search_path(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> Path:
    """A search path of the test's own (and no user config directory), so nothing on the host leaks in."""
    user = tmp_path / "user"
    user.mkdir()
    monkeypatch.setenv("GRIPPERS_PROFILE_PATH", str(user))
    monkeypatch.setenv("XDG_CONFIG_HOME", str(tmp_path / "config"))
    return user


def _shipped(name: str) -> str:
    return (ROOT / "profiles" / f"{name}.toml").read_text(encoding="utf-8")


def _variant(base: str, name: str, *replacements: tuple[str, str], keep_aliases: bool = False) -> str:
    text = _shipped(base).replace(f'name = "{base}"', f'name = "{name}"', 1)
    if not keep_aliases:
        text = "\n".join(line for line in text.splitlines() if not line.startswith("aliases"))
    for old, new in replacements:
        assert old in text, old
        text = text.replace(old, new)
    return text + "\n"


# --- issue 13 item 6: a profile that cannot work is refused at load, naming the field and the rule --------

BAD = [
    ("wsg50", ("stroke_mm = 110.0", "stroke_mm = inf"), "mechanics.stroke_mm", "finite"),
    ("wsg50", ("stroke_mm = 110.0", "stroke_mm = nan"), "mechanics.stroke_mm", "finite"),
    ("wsg50", ("stroke_mm = 110.0", "stroke_mm = 1e308"), "mechanics.stroke_mm", "less than or equal"),
    ("msg-150", ("open_width_mm = 105.0", "open_width_mm = 1e308"), "maps.open_width_mm", "less than"),
    ("msg-150", ("open_width_mm = 105.0", "open_width_mm = 80.0"), "must cover the stroke", "105"),
    ("msg-150", ("newton_per_amp = 40.0", "newton_per_amp = 1e-300"), "maps.newton_per_amp", "no grasp"),
    ("wsg50", ("[wsg]", "[safety]\nmin_width_mm = 80.0\nmax_width_mm = 20.0\n[wsg]"), "safety", "min_width"),
    ("wsg50", ("[wsg]", "[safety]\nmin_width_mm = 120.0\n\n[wsg]"), "safety", "empty"),
    ("wsg50", ("[wsg]", "[safety]\nmax_force_n = 2.0\n\n[wsg]"), "safety.max_force_n", "below"),
    ("wsg50", ("[wsg]", "[safety]\nmax_speed_mm_s = 1.0\n\n[wsg]"), "safety.max_speed_mm_s", "below"),
    ("wsg50", ("[wsg]", "[transport]\ntimeout_s = inf\n\n[wsg]"), "transport.timeout_s", "finite"),
    ("wsg50", ("[wsg]", "[transport]\ntimeout_s = 1e9\n\n[wsg]"), "transport.timeout_s", "less than"),
    ("msg-150", ("[maps]", "[simulator]\ntime_scale = 1e300\n\n[maps]"), "simulator.time_scale", "less than"),
    ("wsg50", ("max_speed_mm_s = 420.0", "max_speed_mm_s = 1e300"), "mechanics.max_speed_mm_s", "less than"),
    ("wsg50", ("max_force_n = 80.0", "max_force_n = inf"), "mechanics.max_force_n", "finite"),
]


@pytest.mark.parametrize(("base", "change", "field", "rule"), BAD, ids=[f"{b[2]}-{b[3]}" for b in BAD])
def test_a_profile_that_cannot_work_is_refused_at_load(
    tmp_path: Path, base: str, change: tuple[str, str], field: str, rule: str
) -> None:
    path = tmp_path / "bad.toml"
    path.write_text(_variant(base, "bad", change), encoding="utf-8")
    with pytest.raises(ProfileError) as caught:
        p.load_file(path)
    message = str(caught.value)
    assert str(path) in message and field in message and rule in message, message


# --- issue 13 item 8: the first match on the search path wins, by name and by alias -----------------------


def test_a_user_profile_named_like_a_builtin_wins_every_lookup(_own_search_path: Path) -> None:
    (_own_search_path / "my-wsg.toml").write_text(
        _variant("wsg50", "wsg50", ("[wsg]", "[safety]\nmax_force_n = 25.0\n\n[wsg]")), encoding="utf-8"
    )
    for name in ("wsg50", "WSG 50", "wsg-50"):  # the name, and the built-in's aliases
        profile = p.load_profile(name)
        assert profile.limits().max_force == 25.0, name
        assert profile.path == str(_own_search_path / "my-wsg.toml")
    with grippers.open(f"sim://wsg50?time_scale={TIME_SCALE}") as g:
        assert g.limits.max_force == 25.0
        with pytest.raises(LimitError, match="force 60 N is outside"):
            g.grasp(0.04, force=60)
    names = [q.name for q in p.list_profiles()]
    assert names.count("wsg50") == 1
    scan = p.scan_profiles()
    assert (str(p.load_profile("wsg50").path)) in {str(q.path) for q in scan.profiles}
    assert any(winner == str(_own_search_path / "my-wsg.toml") for _file, winner in scan.shadowed)


def test_an_invalid_file_that_claims_the_name_is_an_error_not_the_builtin(_own_search_path: Path) -> None:
    (_own_search_path / "mine.toml").write_text(
        _variant("wsg50", "wsg50", ("max_force_n = 80.0", "max_force_n = -25.0")), encoding="utf-8"
    )
    with pytest.raises(ProfileError, match=r"mine\.toml.*mechanics\.max_force_n"):
        p.load_profile("wsg50")
    (_own_search_path / "mine.toml").unlink()
    (_own_search_path / "wsg50.toml").write_text("this is not toml", encoding="utf-8")  # meant to be wsg50
    with pytest.raises(ProfileError, match=r"wsg50\.toml: not valid TOML"):
        p.load_profile("wsg50")


def test_one_invalid_file_does_not_stop_the_listing(_own_search_path: Path) -> None:
    (_own_search_path / "broken.toml").write_text('name = "broken"\nfamily = "wsg"\n', encoding="utf-8")
    (_own_search_path / "garbage.json").write_text("{", encoding="utf-8")
    scan = p.scan_profiles()
    assert {q.name for q in scan.profiles} >= {"wsg50", "msg-150"}
    assert sorted(Path(f).name for f, _ in scan.problems) == ["broken.toml", "garbage.json"]
    assert all(f in why for f, why in scan.problems)
    assert "wsg50" in {q.name for q in p.list_profiles()}  # not strict by default: logged, not raised
    assert p.load_profile("msg-150").name == "msg-150"


# --- issue 13 item 9: parsed once per modification, sizes bounded ----------------------------------------


def test_profiles_are_parsed_once_per_modification(tmp_path: Path) -> None:
    path = tmp_path / "mine.toml"
    path.write_text(_variant("wsg50", "mine"), encoding="utf-8")
    first = p.load_file(path)
    assert p.load_file(path) is first  # cached: no second parse
    lowered = _variant("wsg50", "mine", ("[wsg]", "[safety]\nmax_force_n = 30.0\n[wsg]"))
    path.write_text(lowered, encoding="utf-8")
    os.utime(path, ns=(1, 1))  # a different mtime even on a coarse clock
    second = p.load_file(path)
    assert second is not first and second.limits().max_force == 30.0


def test_a_huge_file_on_the_path_is_refused_unread(_own_search_path: Path) -> None:
    junk = _own_search_path / "junk.toml"
    with junk.open("wb") as f:
        f.truncate(64 << 20)  # 64 MiB, sparse: costs nothing to make, 64 MiB to read
    assert p.validate_file(junk) == [
        f"{junk}: larger than {p.MAX_PROFILE_BYTES} bytes, the most a profile may have; not read"
    ]
    with grippers.open(f"sim://msg-150?time_scale={TIME_SCALE}") as g:  # the path is scanned: no parse
        assert g.profile.name == "msg-150"
    assert [Path(f).name for f, _ in p.scan_profiles().problems] == ["junk.toml"]


# --- issue 16 §6: extends --------------------------------------------------------------------------------


def test_extends_inherits_a_builtin_and_changes_a_few_fields(_own_search_path: Path) -> None:
    (_own_search_path / "soft.toml").write_text(
        'name = "wsg50-soft"\nextends = "wsg50"\ndescription = "WSG 50 for glass"\n\n'
        "[safety]\nmax_force_n = 25.0\n\n[mechanics]\ndefault_force_n = 10.0\n",
        encoding="utf-8",
    )
    soft = p.load_profile("wsg50-soft")
    base = p.load_profile("wsg50")
    assert soft.limits().max_force == 25.0 and soft.mechanics.default_force_n == 10.0
    assert soft.mechanics.stroke_mm == base.mechanics.stroke_mm and soft.wsg == base.wsg
    assert soft.url == base.url and soft.aliases == []  # aliases stay with the base
    assert p.load_profile("WSG 50").name == "wsg50"
    assert "extends" not in soft.model_dump()  # a dump is the complete profile
    with grippers.open(f"sim://wsg50-soft?time_scale={TIME_SCALE}") as g:
        pytest.raises(LimitError, g.grasp, 0.04, force=30)


def test_extends_under_the_same_name_lowers_the_builtin(_own_search_path: Path) -> None:
    (_own_search_path / "wsg50.toml").write_text(
        'name = "wsg50"\nextends = "wsg50"\n\n[safety]\nmax_force_n = 25.0\n', encoding="utf-8"
    )
    assert p.load_profile("wsg50").limits().max_force == 25.0
    assert p.load_profile("WSG 50").limits().max_force == 25.0


def test_extends_cycles_and_unknown_bases_are_refused(_own_search_path: Path) -> None:
    (_own_search_path / "a.toml").write_text('name = "a"\nextends = "b"\n', encoding="utf-8")
    (_own_search_path / "b.toml").write_text('name = "b"\nextends = "a"\n', encoding="utf-8")
    with pytest.raises(ProfileError, match="cycle"):
        p.load_profile("a")
    (_own_search_path / "c.toml").write_text('name = "c"\nextends = "nope"\n', encoding="utf-8")
    with pytest.raises(ProfileError, match=r"c\.toml: extends: no profile named 'nope'"):
        p.load_profile("c")
    (_own_search_path / "d.toml").write_text(
        'name = "d"\nextends = "msg-150"\n[maps]\nopen_width_mm = 50.0\n', encoding="utf-8"
    )
    with pytest.raises(ProfileError, match=r"d\.toml: .*must cover the stroke"):
        p.load_profile("d")


def test_profiles_list_names_the_bad_file_and_lists_the_rest(_own_search_path: Path) -> None:
    import json
    import subprocess
    import sys

    (_own_search_path / "broken.toml").write_text('name = "broken"\nfamily = "wsg"\n', encoding="utf-8")
    run = subprocess.run(
        [sys.executable, "-m", "grippers", "profiles", "list", "--json"],
        capture_output=True,
        text=True,
        env=os.environ.copy(),
        timeout=60,
    )
    assert run.returncode == 0, run.stderr
    document = json.loads(run.stdout)
    assert "wsg50" in {row["name"] for row in document["profiles"]}
    assert [Path(s["file"]).name for s in document["skipped"]] == ["broken.toml"]
    assert "broken.toml" in run.stderr


def test_the_extends_examples_in_docs_profiles_md_load(_own_search_path: Path) -> None:
    import re

    text = (ROOT / "docs" / "profiles.md").read_text(encoding="utf-8")
    blocks = re.findall(r"```toml\n(.*?)```", text, re.S)
    assert len(blocks) == 2
    for i, block in enumerate(blocks):
        (_own_search_path / f"example{i}.toml").write_text(block, encoding="utf-8")
    glass = p.load_profile("wsg50-glass")
    assert glass.limits().max_force == 15.0 and glass.limits().max_speed == pytest.approx(0.05)
    assert p.load_profile("wsg50").limits().max_force == 25.0
