"""Issue 42 §1: ``grippers panel`` prints its address (``--json``: ``{"url": ...}`` first), serves, and
stops on SIGTERM or Ctrl-C; ``grippers --help`` does not load the panel's web stack."""

from __future__ import annotations

import json
import os
import signal
import subprocess
import sys

import httpx
import pytest


def _panel(*args: str) -> subprocess.Popen[str]:
    return subprocess.Popen(
        [sys.executable, "-m", "grippers", "panel", *args],
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,
        text=True,
    )


@pytest.mark.parametrize("how", [signal.SIGTERM, signal.SIGHUP, signal.SIGINT])
def test_panel_json_prints_the_url_first_and_serves(how: signal.Signals) -> None:
    proc = _panel("left=sim://wsg50", "sim://msg-150", "--json")
    try:
        first = json.loads(proc.stdout.readline())  # type: ignore[union-attr]
        url = first["url"]
        assert url.startswith("http://127.0.0.1:") and url.endswith("/")
        names = [g["name"] for g in httpx.get(url + "api/grippers", timeout=5).json()["grippers"]]
        assert names == ["left", "msg-150"]
    finally:
        proc.send_signal(how)
        out, err = proc.communicate(timeout=20)
    assert proc.returncode == (130 if how == signal.SIGINT else 0), err


def test_panel_off_loopback_prints_a_token() -> None:
    proc = _panel("sim://wsg50", "--listen", "0.0.0.0:0")
    try:
        line = proc.stdout.readline()  # type: ignore[union-attr]
        assert line.startswith("panel at http://") and "?token=" in line
        url = line.split()[-1]
        port = url.split(":")[2].split("/")[0]
        assert httpx.get(f"http://127.0.0.1:{port}/", timeout=5).status_code == 401
    finally:
        proc.terminate()
        proc.communicate(timeout=20)


def test_usage_errors_say_what_is_wrong() -> None:
    for args, text in (
        (["sim://wsg50", "--listen", "nowhere"], "HOST:PORT"),
        (["sim://wsg50", "--tls-cert", "x.pem"], "--tls-cert and --tls-key go together"),
        (["a=sim://wsg50", "a=sim://wsg50"], "two grippers named 'a'"),
    ):
        done = subprocess.run(
            [sys.executable, "-m", "grippers", "panel", *args], capture_output=True, text=True, timeout=60
        )
        assert done.returncode == 2, (args, done.stderr)
        assert text in done.stderr and "Traceback" not in done.stderr


def test_help_does_not_load_the_web_stack() -> None:
    code = (
        "import sys, contextlib, io\n"
        "from grippers.cli import main\n"
        "with contextlib.redirect_stdout(io.StringIO()):\n"
        "    for argv in (['--help'], ['panel', '--help']):\n"
        "        try:\n"
        "            main(argv)\n"
        "        except SystemExit:\n"
        "            pass\n"
        "web = ('starlette', 'uvicorn', 'websockets', 'grippers.panel.server', 'grippers.panel.app')\n"
        "print(sorted(m for m in web if m in sys.modules))\n"
    )
    done = subprocess.run(
        [sys.executable, "-c", code], capture_output=True, text=True, timeout=60, env=os.environ
    )
    assert done.stdout.strip() == "[]", done.stderr


def test_serve_http_adds_the_panel_through_the_served_lease() -> None:
    """``serve --http``: the panel's address in --json; the page drives the grippers as a client of the
    server, so a program holding the lease keeps it."""
    pytest.importorskip("zenoh")
    import grippers

    from .conftest import PageClient, wait_for

    proc = subprocess.Popen(
        [
            sys.executable,
            "-m",
            "grippers",
            "serve",
            "left=sim://wsg50?time_scale=20",
            "--listen",
            "tcp/127.0.0.1:0",
            "--http",
            "127.0.0.1:0",
            "--json",
        ],
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,
        text=True,
    )
    try:
        doc = json.loads(proc.stdout.readline())  # type: ignore[union-attr]
        assert doc["schema"] == "grippers.serve/1" and doc["panel"].startswith("http://127.0.0.1:")
        listing = httpx.get(doc["panel"] + "api/grippers", timeout=5).json()["grippers"]
        assert [g["name"] for g in listing] == ["left"] and listing[0]["remote"] is True
        with grippers.open(doc["grippers"][0]["url"] + "&label=robot") as robot:
            robot.acquire_control()

            class _Server:  # PageClient needs the panel's port only
                port = int(doc["panel"].rsplit(":", 1)[1].strip("/"))
                token = None

            page = PageClient(_Server())  # type: ignore[arg-type]
            try:
                page.command("left", "home")  # started; the server's refusal ends it
                (refused,) = wait_for(lambda: page.done, "the home's outcome")
                assert refused["error"] == "AccessDenied" and "robot" in refused["message"], refused
                assert page.command("left", "stop")["ok"]  # never refused
                robot.release_control()
                assert page.command("left", "home")["ok"]
            finally:
                page.close()
    finally:
        proc.send_signal(signal.SIGTERM)
        out, err = proc.communicate(timeout=30)
    assert proc.returncode == 0, err
