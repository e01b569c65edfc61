"""Issue 31 §5: the vocabulary table of docs/api.md names only methods and attributes that exist.

A Robotiq or ur_rtde user reaches for ``activate()``, ``open()``, ``close()`` and ``goTo()``; the table maps
them to ours, and a table that named a method we do not have would send them to an AttributeError.
"""

from __future__ import annotations

import dataclasses
import inspect
import re

import grippers
import grippers.aio

from .conftest import ROOT

CALL = re.compile(r"^([a-z_]+)\(")


def _our_column() -> list[str]:
    text = (ROOT / "docs" / "api.md").read_text(encoding="utf-8")
    section = text.split("## Vocabulary", 1)[1].split("\n## ", 1)[0]
    rows = [line for line in section.splitlines() if line.startswith("| ") and "---" not in line]
    header, *body = rows
    assert header.rstrip(" |").endswith("grippers"), header
    assert len(body) >= 10
    names: list[str] = []
    for row in body:
        cell = row.rstrip(" |").rsplit("|", 1)[1]
        found = re.findall(r"`([^`]+)`", cell)
        assert found, row
        names += found
    return names


def _fields(cls: type) -> set[str]:
    if dataclasses.is_dataclass(cls):
        return {f.name for f in dataclasses.fields(cls)}
    return set(getattr(cls, "model_fields", {})) | set(vars(cls))


def test_the_table_maps_the_vocabularies_users_bring() -> None:
    section = (ROOT / "docs" / "api.md").read_text(encoding="utf-8").split("## Vocabulary", 1)[1]
    table = section.split("\n## ", 1)[0]
    for word in ("Robotiq", "ur_rtde", "Franka", "franky", "SCHUNK", "activate", "homing", "rGTO", "close()"):
        assert word in table, word
    for intent in ("open fully", "close on a part", "go to a width", "stop", "end the session"):
        assert intent in section


def test_every_name_in_our_column_exists() -> None:
    names = _our_column()
    assert {"home()", "release()", "move(width, speed)", "stop()", "close()"} <= set(names)
    results = {
        "state()": grippers.GripperState,
        "info()": grippers.DeviceInfo,
    }
    for name in names:
        head, _, rest = name.partition(".")
        method = CALL.match(head)
        if method is None:  # GraspResult.grasped: a result's field
            cls = getattr(grippers, head)
            assert rest in _fields(cls), name
            continue
        attr = method.group(1)
        for face in (grippers.Gripper, grippers.aio.AsyncGripper):
            assert callable(getattr(face, attr, None)), f"{face.__name__} has no {attr}() ({name})"
        params = set(inspect.signature(getattr(grippers.Gripper, attr)).parameters)
        args = [a.strip().split("=")[0] for a in head[len(attr) + 1 : -1].split(",") if a.strip()]
        assert set(args) <= params, f"{name}: {set(args) - params} are not parameters of {attr}()"
        if rest:
            assert rest in _fields(results[f"{attr}()"]), name


def test_close_says_it_does_not_move_the_jaws() -> None:
    for face in (grippers.Gripper, grippers.aio.AsyncGripper):
        doc = inspect.getdoc(face.close) or ""
        assert "does not move the jaws" in doc, face


def test_the_readme_points_to_the_table() -> None:
    readme = (ROOT / "README.md").read_text(encoding="utf-8")
    python = readme.split("## Python", 1)[1].split("\n## ", 1)[0]
    assert "docs/api.md" in python and "Vocabulary" in python and "close()" in python
