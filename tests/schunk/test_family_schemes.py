"""A family's own schemes reach every command that takes a URL (issue 41 §1; issue 39 §1, second bullet):
``grippers probe`` and ``grippers monitor`` took ``robotiq+urcap://`` as an unknown scheme although ``grippers
sim`` prints it; ``schunk+http://`` is the same case."""

from __future__ import annotations

import json
import subprocess
import sys
import time
from collections.abc import Iterator
from typing import Any

import pytest

from grippers.backends import get_backend
from grippers.profiles import load_profile
from grippers.settings import Settings
from grippers.urls import family_scheme, parse_url


@pytest.fixture
def urcap_url() -> Iterator[str]:
    server = get_backend("robotiq").simulator(
        load_profile("robotiq-2f85"),
        Settings("sim://robotiq-2f85", {"activated": "true"}, {}),
        "urcap://127.0.0.1:0",
    )
    yield server.url
    server.close()
    assert server.error is None


def _grippers(*args: str, timeout: float = 60.0) -> subprocess.CompletedProcess[str]:
    return subprocess.run(
        [sys.executable, "-m", "grippers", *args], capture_output=True, text=True, timeout=timeout
    )


def _probe(url: str) -> dict[str, Any]:
    proc = _grippers("probe", url, "--json")
    assert proc.returncode == 0, (proc.stdout, proc.stderr)
    return json.loads(proc.stdout)


def test_probe_takes_the_urcap_scheme_grippers_sim_prints(urcap_url: str) -> None:
    assert urcap_url.startswith("robotiq+urcap://")
    found = _probe(urcap_url)
    assert json.dumps(found).count(urcap_url) >= 1, found


def test_probe_takes_a_schunk_web_api_url(schunk_sim) -> None:
    server = schunk_sim("schunk-egu-60")
    found = _probe(server.url)
    assert "EGU 60" in json.dumps(found), found


def test_monitor_takes_the_urcap_scheme(urcap_url: str) -> None:
    proc = subprocess.Popen(
        [sys.executable, "-m", "grippers", "monitor", urcap_url],
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,
    )
    try:
        deadline = time.monotonic() + 20
        while proc.poll() is None and time.monotonic() < deadline:
            time.sleep(0.05)
            if time.monotonic() > deadline - 15:  # running for five seconds: it took the URL
                break
        assert proc.poll() is None, proc.communicate(timeout=5)
    finally:
        proc.terminate()
        proc.wait(10)


def test_the_grammar_knows_only_installed_families_own_schemes() -> None:
    assert family_scheme("robotiq+urcap") and family_scheme("schunk+http") and family_scheme("wsg+tcp")
    assert not family_scheme("wsg+http") and not family_scheme("nobody+tcp")
    u = parse_url("schunk+http://10.0.0.5:8080")
    assert (u.family, u.transport, u.host, u.port, u.params) == (
        "schunk",
        "tcp",
        "10.0.0.5",
        8080,
        {"protocol": "http"},
    )
    assert u.url == "schunk+http://10.0.0.5:8080"
    with pytest.raises(ValueError, match="protocol"):
        parse_url("schunk+http://10.0.0.5?protocol=rtu")
