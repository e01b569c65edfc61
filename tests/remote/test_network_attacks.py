"""Issue 23 §1 and §3 on the network: what someone exploring the key space types first must not stop or move
anything; a second server of a served name is refused; absurd numbers are typed errors."""

from __future__ import annotations

import json
import subprocess
import sys

import pytest

import grippers

from .conftest import ROOT, ServeProcess, sim
from .test_faults import _raw_session

pytestmark = pytest.mark.timeout(90)


def _request(**args: object) -> bytes:
    return json.dumps({"v": 1, "client": "explorer", "label": "z_get", "args": args}).encode()


def test_a_bare_wildcard_get_stops_nothing(serve) -> None:
    """`z_get -s 'grippers/**'` reaches every queryable of every gripper, fast_stop included. Before: both
    grippers were fast-stopped by it. Now a query without payload, or on a pattern, is never a command."""
    server: ServeProcess = serve(f"a={sim('wsg50')}", f"b={sim('wsg50')}")
    clients = [grippers.open(server.urls[n]) for n in ("a", "b")]
    session = _raw_session(server.endpoint)
    try:
        for g in clients:
            g.home()
            g.move(0.06)
        for selector, payload in [
            ("grippers/**", None),  # the explorer's first query
            ("grippers/*/cmd/*", None),
            ("grippers/*/cmd/fast_stop", _request()),  # a pattern, even with a valid request
            ("grippers/**", _request()),
            ("grippers/a/cmd/*", _request(width=0.02)),
        ]:
            replies = list(session.get(selector, payload=payload, timeout=3))
            errors = [r for r in replies if r.err is not None]
            assert errors, selector  # told why, not silently ignored
            for r in errors:
                doc = json.loads(r.err.payload.to_bytes())
                assert doc["error"] == "ProtocolError", doc
        for g in clients:
            st = g.state()
            assert not st.fast_stopped
            assert st.width == pytest.approx(0.06, abs=0.002)  # nothing moved
            g.move(0.05)  # still commandable: no fast stop to acknowledge
        # The exact key with a request is a command, as before.
        replies = list(session.get("grippers/a/cmd/stop", payload=_request(), timeout=3))
        assert len(replies) == 1 and replies[0].ok is not None
    finally:
        session.close()
        for g in clients:
            g.close()


@pytest.mark.parametrize("digits", [400, 1000])
def test_a_huge_integer_in_a_request_is_a_protocol_error(serve, digits: int) -> None:
    server: ServeProcess = serve(f"g={sim('wsg50')}")
    session = _raw_session(server.endpoint)
    try:
        payload = b'{"v": 1, "client": "x", "args": {"width": 1' + b"0" * (digits - 1) + b"}}"
        replies = list(session.get("grippers/g/cmd/move", payload=payload, timeout=3))
        assert len(replies) == 1 and replies[0].err is not None
        doc = json.loads(replies[0].err.payload.to_bytes())
        assert doc["error"] == "ProtocolError" and "too large" in doc["message"], doc  # not a server bug
    finally:
        session.close()


def test_a_second_server_of_a_served_name_is_refused(serve) -> None:
    """Both used to answer every query and their state streams mixed. The second refuses before declaring
    anything, naming what the first serves; the first goes on serving untouched."""
    first: ServeProcess = serve(f"g={sim('wsg50')}")
    cmd = [sys.executable, "-m", "grippers", "serve", f"g={sim('msg-150')}", "other=" + sim("wsg50")]
    cmd += ["--listen", "tcp/127.0.0.1:0", "--connect", first.endpoint]
    out = subprocess.run(cmd, cwd=ROOT, capture_output=True, text=True, timeout=60)
    assert out.returncode == 1, out
    assert "already served" in out.stderr and "wsg" in out.stderr.lower(), out.stderr
    assert "serving at" not in out.stdout  # nothing was served, not even the other name
    with grippers.open(first.urls["g"]) as g:
        assert g.info().model.lower().startswith("wsg")
        for _ in range(3):  # one server answers: every state is the WSG's
            g.state()
    # A different name next to it is fine.
    second = ServeProcess(f"h={sim('wsg50')}", "--connect", first.endpoint)
    try:
        with grippers.open(second.urls["h"]) as h:
            h.state()
    finally:
        second.close()
