"""Every CLI command over ``zenoh://`` (in this process, against a server in another), probe, and serve's
own usage errors. --json output is checked against the CLI's schemas."""

from __future__ import annotations

import json
from collections.abc import Iterator
from typing import Any

import pytest

from grippers.cli import main
from grippers.cli.schemas import validate

from .conftest import ServeProcess, sim

pytestmark = pytest.mark.timeout(60)


@pytest.fixture(scope="module")
def server() -> Iterator[ServeProcess]:
    s = ServeProcess(f"left={sim('wsg50', part_width_mm=30)}", f"right={sim('msg-150')}")
    yield s
    s.close()


def run(capsys: pytest.CaptureFixture[str], *argv: str) -> tuple[int, Any, str]:
    """Exit code, the --json document (validated) or the plain output, and stderr."""
    code = main(list(argv))
    out = capsys.readouterr()
    doc: Any = out.out
    if "--json" in argv and out.out.strip():
        doc = json.loads(out.out)
        validate(doc)
    return code, doc, out.err


def test_every_command_over_zenoh(server: ServeProcess, capsys: pytest.CaptureFixture[str]) -> None:
    url = server.urls["left"]
    assert run(capsys, "home", url, "--json")[1]["state"]["referenced"] is True
    code, doc, _ = run(capsys, "move", url, "40", "--speed", "50", "--json")
    assert code == 0 and doc["result"]["width_mm"] == pytest.approx(40.0, abs=0.5)
    assert run(capsys, "state", url, "--json")[1]["state"]["width_mm"] == pytest.approx(40.0, abs=0.5)
    info = run(capsys, "info", url, "--json")[1]["info"]
    assert info["family"] == "wsg" and info["model"] == "WSG 50" and info["limits"]["max_force_n"] == 80
    code, doc, _ = run(capsys, "grasp", url, "25", "--force", "20", "--json")
    assert code == 0 and doc["result"]["grasped"] and doc["result"]["grasp_state"] == "holding"
    assert run(capsys, "release", url, "60", "--json")[1]["result"]["width_mm"] == pytest.approx(60, abs=0.5)
    assert run(capsys, "stop", url, "--json")[0] == 0
    assert run(capsys, "stop", url, "--fast", "--json")[0] == 0
    code, _, err = run(capsys, "move", url, "50")
    assert code == 1 and "fast stop" in err.lower()
    assert run(capsys, "ack", url, "--json")[0] == 0
    code, _, err = run(capsys, "move", url, "500")
    assert code == 2 and "outside" in err  # a LimitError from the served limits: a usage error
    code, text, _ = run(capsys, "state", url, "--watch", "--count", "3", "--interval", "0.02")
    assert code == 0 and len(text.splitlines()) == 3
    code, _, err = run(capsys, "state", "zenoh://nobody?connect=" + server.endpoint, "--timeout", "0.3")
    assert code == 1 and "no answer" in err


def test_probe_lists_what_is_served(server: ServeProcess, capsys: pytest.CaptureFixture[str]) -> None:
    code, doc, _ = run(capsys, "probe", f"zenoh://?connect={server.endpoint}", "--json")
    assert code == 0
    found = {d["url"].split("?")[0]: d for d in doc["grippers"]}
    assert set(found) == {"zenoh://left", "zenoh://right"}
    assert found["zenoh://left"]["model"] == "WSG 50" and found["zenoh://right"]["family"] == "stepfoc"
    code, text, _ = run(capsys, "probe", f"zenoh://?connect={server.endpoint}")
    assert code == 0 and "WSG 50" in text and "zenoh://left?connect=" in text


def test_serve_usage_errors(capsys: pytest.CaptureFixture[str]) -> None:
    assert main(["serve", "bad*name=sim://wsg50", "--listen", "tcp/127.0.0.1:0"]) == 2
    assert "served name" in capsys.readouterr().err
    assert main(["serve", "a=sim://wsg50?time_scale=50", "a=sim://wsg50?time_scale=50"]) == 2
    assert "two grippers named" in capsys.readouterr().err


def test_serve_json_prints_what_is_served_where() -> None:
    import signal
    import subprocess
    import sys

    proc = subprocess.Popen(
        [
            sys.executable,
            "-m",
            "grippers",
            "serve",
            f"left={sim('wsg50')}",
            "--listen",
            "tcp/127.0.0.1:0",
            "--json",
        ],
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,
        text=True,
    )
    try:
        assert proc.stdout is not None
        doc = json.loads(proc.stdout.readline())
        validate(doc)
        (left,) = doc["grippers"]
        assert doc["schema"] == "grippers.serve/1" and left["name"] == "left"
        assert left["url"].startswith("zenoh://left?connect=tcp/127.0.0.1:")
    finally:
        proc.send_signal(signal.SIGTERM)
        proc.communicate(timeout=20)
