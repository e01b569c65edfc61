"""Issue 33 §1: ``selftest --write-profile FILE`` checks FILE before anything moves, writes it whole or not at
all, never writes through a symbolic link, and never loses the results table.

The refusals run against a WSG simulator in this process, so the test reads from the simulator itself that
nothing moved (the jaws are still unreferenced). Runs that complete use a ``sim://`` URL at 20x real time.
"""

from __future__ import annotations

import os
import tomllib
from pathlib import Path
from typing import Any

import pytest

from grippers.cli import main
from grippers.profiles import MAX_EXTENDS_DEPTH, load_profile

SIM = "sim://{name}?time_scale=20"


@pytest.fixture
def bench(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> Path:
    """A profile folder on the search path holding ``mywsg`` (extends wsg50): a user's own base profile."""
    folder = tmp_path / "profiles"
    folder.mkdir()
    (folder / "mywsg.toml").write_text('name = "mywsg"\nextends = "wsg50"\n[safety]\nmax_force_n = 60.0\n')
    monkeypatch.setenv("GRIPPERS_PROFILE_PATH", str(folder))
    monkeypatch.chdir(tmp_path)
    return folder


def _selftest(capsys: pytest.CaptureFixture[str], *argv: str) -> tuple[int, str, str]:
    code = main(["selftest", *argv, "--yes"])
    out, err = capsys.readouterr()
    return code, out, err


def _refused_before_moving(wsg_sim: Any, capsys: pytest.CaptureFixture[str], *argv: str) -> str:
    server = wsg_sim("tcp://127.0.0.1:0")
    code, out, err = _selftest(capsys, server.url, "--profile", "mywsg", *argv)
    lines = [ln for ln in err.splitlines() if ln.strip()]
    assert code == 2 and len(lines) == 1 and "Traceback" not in err, (code, out, err)
    assert "will move" not in err and not out  # refused before the plan was even shown
    assert server.model.referenced is False  # nothing moved: not even homed
    return lines[0]


def test_the_base_profiles_own_file_is_refused_even_with_force(wsg_sim, capsys, bench: Path) -> None:
    # Before: the file became a profile extending itself; nothing loaded, `info sim://mywsg` failed after.
    own = bench / "mywsg.toml"
    before = own.read_text()
    for extra in ((), ("--force",)):
        line = _refused_before_moving(wsg_sim, capsys, "--write-profile", str(own), *extra)
        assert "is the file of the base profile 'mywsg'" in line, line
    assert own.read_text() == before
    assert load_profile("mywsg").safety.max_force_n == 60.0


def test_a_file_the_base_extends_is_refused(wsg_sim, capsys, bench: Path) -> None:
    (bench / "mywsg-glass.toml").write_text('name = "mywsg-glass"\nextends = "mywsg"\n')
    server = wsg_sim("tcp://127.0.0.1:0")
    code, _, err = _selftest(
        capsys,
        server.url,
        "--profile",
        "mywsg-glass",
        "--write-profile",
        str(bench / "mywsg.toml"),
        "--force",
    )
    assert code == 2 and "(or of one it extends)" in err, err
    assert server.model.referenced is False


@pytest.mark.parametrize(
    ("name", "says"),
    [
        ("out.TOML", "must end in .toml (lower case"),
        ("folder.toml", "is a directory"),
        ("missing/out.toml", "no folder"),
        ("taken.toml", "the file exists; add --force to replace it"),
        ("link.toml", "is a symbolic link (to mywsg-copy.toml)"),
        ("dangling.toml", "is a symbolic link (to nowhere.toml)"),
    ],
)
def test_a_target_that_cannot_be_written_is_refused_before_moving(
    wsg_sim, capsys, bench: Path, tmp_path: Path, name: str, says: str
) -> None:
    (tmp_path / "folder.toml").mkdir()
    (tmp_path / "taken.toml").write_text("# mine\n")
    (tmp_path / "mywsg-copy.toml").write_text("# the link's target\n")
    (tmp_path / "link.toml").symlink_to("mywsg-copy.toml")
    (tmp_path / "dangling.toml").symlink_to("nowhere.toml")
    line = _refused_before_moving(wsg_sim, capsys, "--write-profile", name)
    assert says in line, line
    assert (tmp_path / "taken.toml").read_text() == "# mine\n"
    assert (tmp_path / "mywsg-copy.toml").read_text() == "# the link's target\n"
    assert not (tmp_path / "nowhere.toml").exists()


def test_a_symbolic_link_is_refused_even_with_force(wsg_sim, capsys, bench: Path, tmp_path: Path) -> None:
    (tmp_path / "real.toml").write_text("# real\n")
    (tmp_path / "link.toml").symlink_to("real.toml")
    line = _refused_before_moving(wsg_sim, capsys, "--write-profile", "link.toml", "--force")
    assert "symbolic link" in line
    assert (tmp_path / "real.toml").read_text() == "# real\n" and (tmp_path / "link.toml").is_symlink()


def test_a_chain_one_level_too_deep_is_refused_before_moving(wsg_sim, capsys, bench: Path) -> None:
    # deepN stands on N + 1 levels; the written profile adds one: the cap's own level leaves no room.
    (bench / "deep0.toml").write_text('name = "deep0"\nextends = "wsg50"\n')
    for i in range(1, MAX_EXTENDS_DEPTH):
        (bench / f"deep{i}.toml").write_text(f'name = "deep{i}"\nextends = "deep{i - 1}"\n')
    base = f"deep{MAX_EXTENDS_DEPTH - 1}"
    assert load_profile(base).name == base  # the base itself loads
    server = wsg_sim("tcp://127.0.0.1:0")
    code, out, err = _selftest(capsys, server.url, "--profile", base, "--write-profile", "out.toml")
    assert code == 2 and f"more than {MAX_EXTENDS_DEPTH} levels of extends" in err, err
    assert len(err.strip().splitlines()) == 1 and server.model.referenced is False
    assert not Path("out.toml").exists()


def test_a_bad_profile_name_is_refused_before_moving(wsg_sim, capsys, bench: Path) -> None:
    line = _refused_before_moving(
        wsg_sim, capsys, "--write-profile", "out.toml", "--profile-name", "My Unit!"
    )
    assert "would not load" in line and "name" in line


def test_force_replaces_an_existing_file_whole(capsys, bench: Path, tmp_path: Path) -> None:
    target = tmp_path / "bench.toml"
    target.write_text("# an older measurement\n")
    inode = target.stat().st_ino
    code, out, err = _selftest(capsys, SIM.format(name="mywsg"), "--write-profile", "bench.toml", "--force")
    assert code in (0, 3), err
    assert f"wrote {target}" in out and "verdict" in out
    data = tomllib.loads(target.read_text())
    assert data["extends"] == "mywsg" and data["name"] == "mywsg-measured"
    assert target.stat().st_ino != inode  # renamed into place, not rewritten in place
    assert [p.name for p in tmp_path.iterdir() if p.name.startswith(".bench.toml")] == []  # no temporary left
    assert oct(target.stat().st_mode & 0o777) == oct(0o666 & ~_umask())


def test_the_results_are_printed_when_the_file_cannot_be_written(
    capsys, bench: Path, tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    # The target is free when the run starts; a file of that name appears while the jaws move. The run's
    # table is still printed, the newcomer is kept, and the error says why.
    from grippers.cli import selftest

    faults = selftest._Run.faults

    def appear_at_the_end(self: Any, when: str) -> None:
        faults(self, when)
        if when == "after":
            (tmp_path / "late.toml").write_text("# someone else's\n")

    monkeypatch.setattr(selftest._Run, "faults", appear_at_the_end)
    code, out, err = _selftest(capsys, SIM.format(name="mywsg"), "--write-profile", "late.toml")
    assert code == 2, (out, err)
    assert "verdict" in out and "close without a part" in out and "the profile was not written" in out
    assert "appeared during the run" in err and "Traceback" not in err
    assert (tmp_path / "late.toml").read_text() == "# someone else's\n"


def test_json_keeps_the_document_when_the_file_cannot_be_written(
    capsys, bench: Path, tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    import json

    from grippers.cli import selftest

    faults = selftest._Run.faults

    def appear_at_the_end(self: Any, when: str) -> None:
        faults(self, when)
        if when == "after":
            (tmp_path / "late.toml").mkdir()

    monkeypatch.setattr(selftest._Run, "faults", appear_at_the_end)
    code, out, err = _selftest(capsys, SIM.format(name="mywsg"), "--write-profile", "late.toml", "--json")
    assert code == 2 and "is a directory" in err
    doc = json.loads(out)
    assert doc["written_profile"] is None and any(
        ln["check"] == "close without a part" for ln in doc["lines"]
    )


def _umask() -> int:
    mask = os.umask(0o022)
    os.umask(mask)
    return mask


@pytest.mark.parametrize(
    "argv",
    [
        ("--time-scale", "1e308"),  # was an errno tuple after homing and moving
        ("--time-scale", "1e400"),
        ("--time-scale", "nan"),
        ("--time-scale", "0"),
        ("--time-scale", "1e-300"),
        ("--tolerance", "1e308"),  # every speed would pass
        ("--tolerance", "0"),
    ],
)
def test_absurd_numbers_are_usage_errors_before_moving(wsg_sim, capsys, argv: tuple[str, ...]) -> None:
    server = wsg_sim("tcp://127.0.0.1:0")
    with pytest.raises(SystemExit) as exited:
        main(["selftest", server.url, "--yes", *argv])
    err = capsys.readouterr().err
    assert exited.value.code == 2 and f"argument {argv[0]}" in err and len(err.strip().splitlines()) == 1
    assert server.model.referenced is False
