"""Issue 22 §4: the API reference is built from the docstrings, with warnings as errors, and the public API
has the docstrings it is built from (with a Raises section where a call talks to the device)."""

from __future__ import annotations

import inspect
import os
import subprocess
import sys
from pathlib import Path

import pytest

import grippers
from grippers.cli.doctor import SEE

ROOT = Path(__file__).resolve().parents[2]


def _public_callables() -> list[tuple[str, object]]:
    out: list[tuple[str, object]] = []
    for name in grippers.__all__:
        obj = getattr(grippers, name)
        if not (inspect.isclass(obj) or inspect.isfunction(obj)):
            continue
        out.append((name, obj))
        if inspect.isclass(obj) and not issubclass(obj, BaseException):
            for attr, value in vars(obj).items():
                if attr.startswith("_"):
                    continue
                fn = value.fget if isinstance(value, property) else value
                if inspect.isfunction(fn):
                    out.append((f"{name}.{attr}", fn))
    return out


def test_every_public_class_function_and_method_has_a_docstring() -> None:
    missing = [name for name, obj in _public_callables() if not inspect.getdoc(obj)]
    assert missing == []


@pytest.mark.parametrize("name", ["open", "load_profile", "Gripper.state", "Gripper.info"])
def test_calls_that_talk_to_the_device_document_what_they_raise(name: str) -> None:
    obj = grippers
    for part in name.split("."):
        obj = getattr(obj, part)
    assert "Raises:" in (inspect.getdoc(obj) or "")


def test_the_docs_build_with_warnings_as_errors(tmp_path: Path) -> None:
    proc = subprocess.run(
        ["bash", str(ROOT / "scripts" / "build-docs.sh"), str(tmp_path / "site")],
        cwd=ROOT,
        capture_output=True,
        text=True,
        timeout=300,
        env={**os.environ, "PATH": f"{Path(sys.executable).parent}{os.pathsep}{os.environ.get('PATH', '')}"},
    )  # the script's ``python`` is this interpreter's, activated or not
    assert proc.returncode == 0, proc.stderr[-3000:]
    api = (tmp_path / "site" / "api" / "index.html").read_text()
    for name in ("grippers.open", "ProfileAssumed", "GripperTimeout"):
        assert name in api
    for page in ("getting-started-wsg", "getting-started-msg", "troubleshooting", "logging"):
        assert (tmp_path / "site" / page / "index.html").exists()
    # every section the doctor's checks link to is on the troubleshooting page
    trouble = (tmp_path / "site" / "troubleshooting" / "index.html").read_text()
    for anchor in set(SEE.values()):
        assert f'id="{anchor[1:]}"' in trouble, anchor


def test_doctor_links_every_check_that_is_not_ok_to_troubleshooting(cli) -> None:
    doc = cli("doctor", "--json").json()
    for check in doc["checks"]:
        if check["status"] == "ok":
            assert check["see"] is None
        else:
            assert check["see"].startswith("docs/troubleshooting.md#"), check
