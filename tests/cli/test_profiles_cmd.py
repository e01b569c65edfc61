"""`grippers profiles`: list, show, validate (exit 1 on an invalid file), path and the JSON Schema export."""

from __future__ import annotations

import json
import os
import subprocess
import sys
from pathlib import Path

BUILTIN = {
    *("wsg25", "wsg32", "wsg50", "wsg70", "msg-100", "msg-150", "msg-200"),
    *("robotiq-2f85", "robotiq-2f140", "robotiq-hande"),
    *("schunk-egu-60", "schunk-egk-25"),
}


def test_list_and_show(cli, cli_json) -> None:
    rows = cli_json("profiles", "list")["profiles"]
    assert {r["name"] for r in rows} == BUILTIN
    wsg50 = next(r for r in rows if r["name"] == "wsg50")
    assert wsg50["family"] == "wsg" and wsg50["stroke_mm"] == 110.0
    shown = cli_json("profiles", "show", "WSG 50")["profile"]  # an alias works too
    assert shown["name"] == "wsg50" and shown["mechanics"]["max_force_n"] == 80.0
    r = cli("profiles")
    assert r.returncode == 0 and "msg-150" in r.stdout and "110 mm" in r.stdout


def test_validate_names_the_file_and_field_and_exits_1(tmp_path: Path, cli) -> None:
    good = tmp_path / "good.toml"
    bad = tmp_path / "bad.toml"
    text = (Path(__file__).resolve().parents[2] / "profiles" / "wsg50.toml").read_text()
    good.write_text(text.replace('name = "wsg50"', 'name = "my-wsg"'))
    bad.write_text(text.replace("stroke_mm = 110.0", "stroke_mm = -1"))
    r = cli("profiles", "validate", str(good), str(bad), "--json")
    assert r.returncode == 1
    results = {Path(v["file"]).name: v for v in r.json()["validation"]}
    assert results["good.toml"]["valid"] and not results["bad.toml"]["valid"]
    (problem,) = results["bad.toml"]["problems"]
    assert "bad.toml" in problem and "mechanics.stroke_mm" in problem
    assert cli("profiles", "validate", str(good)).returncode == 0


def test_user_profiles_on_the_search_path(tmp_path: Path, cli) -> None:
    text = (Path(__file__).resolve().parents[2] / "profiles" / "msg-150.toml").read_text()
    (tmp_path / "lab.toml").write_text(text.replace('name = "msg-150"', 'name = "lab-msg"'))
    out = subprocess.run(
        [sys.executable, "-m", "grippers", "profiles", "list"],
        capture_output=True,
        text=True,
        timeout=30,
        env={**os.environ, "GRIPPERS_PROFILE_PATH": str(tmp_path)},
    )
    assert out.returncode == 0 and "lab-msg" in out.stdout and str(tmp_path / "lab.toml") in out.stdout


def test_schema_export(cli) -> None:
    r = cli("profiles", "schema")
    assert r.returncode == 0
    schema = json.loads(r.stdout)
    text = json.dumps(schema)
    # The union of the installed families' models, each told apart by its family (issue 28 §2).
    assert "WsgProfile" in text and "MsgProfile" in text and "RobotiqProfile" in text
    assert schema["discriminator"]["propertyName"] == "family"
