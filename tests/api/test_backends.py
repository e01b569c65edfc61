"""Backends register like python-can interfaces: a built-in table plus ``grippers.backends`` entry points."""

from __future__ import annotations

import sys
import textwrap
from pathlib import Path

import pytest

import grippers
from grippers import URLError
from grippers.backends import _cache, available_backends, get_backend


def test_builtins_are_listed() -> None:
    assert {"wsg", "stepfoc"} <= set(available_backends())


def test_unknown_family_is_a_url_error() -> None:
    with pytest.raises(URLError, match="acme"):
        grippers.open("acme+tcp://127.0.0.1:9")


def test_third_party_backend_via_entry_point(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    """A plugin installed as a distribution (a dist-info with entry_points.txt) is found without any change
    here, and its gripper runs the common interface, limit checks included."""
    (tmp_path / "acme_grippers.py").write_text(
        textwrap.dedent(
            """
            import time
            from grippers.device import Device
            from grippers.gripper import Gripper, GripperState, GraspState, MotionResult, GraspResult
            from grippers.profiles import load_profile

            class AcmeDevice(Device):
                width = 0.0
                def home(self, timeout): pass
                def move(self, width, speed, timeout):
                    self.width = width
                    return MotionResult(width, GraspState.IDLE)
                def grasp(self, width, speed, force, timeout):
                    return GraspResult(True, width, force, GraspState.HOLDING)
                def stop(self): pass
                def read_state(self):
                    t = time.time()
                    return GripperState(self.width, 0.0, 0.0, None, GraspState.IDLE, False, True, (), t)
                def info(self): raise NotImplementedError
                def close(self): pass

            class AcmeBackend:
                family = "acme"
                profile_model = None
                def open(self, url, profile, settings):
                    return Gripper(AcmeDevice(), profile or load_profile("wsg50"), url.url, timeout=1.0)
            """
        )
    )
    dist = tmp_path / "acme_grippers-1.0.dist-info"
    dist.mkdir()
    (dist / "METADATA").write_text("Metadata-Version: 2.1\nName: acme-grippers\nVersion: 1.0\n")
    (dist / "entry_points.txt").write_text("[grippers.backends]\nacme = acme_grippers:AcmeBackend\n")
    monkeypatch.syspath_prepend(str(tmp_path))
    monkeypatch.delitem(_cache, "acme", raising=False)
    try:
        assert "acme" in available_backends()
        assert get_backend("acme").family == "acme"
        with grippers.open("acme+tcp://127.0.0.1:9") as g:
            assert g.move(0.05).width == 0.05
            with pytest.raises(grippers.LimitError):
                g.move(1.0)
    finally:
        _cache.pop("acme", None)
        sys.modules.pop("acme_grippers", None)
