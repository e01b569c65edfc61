"""Issue 43 §3: identities are names, not patterns. Ids, served names and labels are checked once
(grippers/remote/protocol.py: an alphabet, a length) and every key expression is built from checked chunks."""

from __future__ import annotations

import json
import subprocess
import sys

import pytest

import grippers
from grippers import ProtocolError, URLError
from grippers.remote import protocol

from .conftest import ROOT, ServeProcess, sim
from .test_faults import _raw_session

pytestmark = pytest.mark.timeout(90)


def _acquire(client: str, label: str = "test") -> bytes:
    return json.dumps({"v": 1, "client": client, "label": label, "args": {"action": "acquire"}}).encode()


@pytest.mark.parametrize("client", ["cell/arm-1", "*", "**", "a$b", "x?y", "-x", "é", "a" * 129, "a\n"])
def test_a_client_id_that_is_not_one_key_chunk_is_refused(client: str) -> None:
    with pytest.raises(ProtocolError, match="client id"):
        protocol.parse_request("control", _acquire(client))
    with pytest.raises(ValueError):
        protocol.client_key("g", client)


@pytest.mark.parametrize("label", ["\x1b[31mred", "two\nlines", "tab\there", "nul\x00", "rlo\u202e"])
def test_a_label_with_control_characters_is_refused(label: str) -> None:
    with pytest.raises(ProtocolError, match="printable"):
        protocol.parse_request("control", _acquire("c1", label))
    with pytest.raises(URLError, match="printable|a control character"):  # the URL parser's, or ours
        grippers.open("zenoh://g?connect=tcp/127.0.0.1:9&label=" + label.replace("\n", "%0A"))


def test_valid_ids_and_labels_pass() -> None:
    request = protocol.parse_request("control", _acquire("0f3a" * 8, "lab bench 3 — Ana"))
    assert request.client == "0f3a" * 8
    assert protocol.client_key("left.arm_1", "c-1") == "grippers/left.arm_1/client/c-1"


@pytest.mark.parametrize("name", ["abc\n", "a/b", "x?y", "a/**", "*", "a$", ""])
def test_key_builders_take_only_checked_names(name: str) -> None:
    for build in (protocol.token_key, protocol.state_key, protocol.all_clients_key):
        with pytest.raises(ValueError, match="served name"):
            build(name)


@pytest.mark.parametrize("name", ["abc\n", "a/b", "x?y", "a/**"])
def test_serve_says_what_is_wrong_with_the_served_name(name: str) -> None:
    cmd = [sys.executable, "-m", "grippers", "serve", f"{name}=sim://wsg50", "--listen", "tcp/127.0.0.1:0"]
    out = subprocess.run(cmd, cwd=ROOT, capture_output=True, text=True, timeout=60)
    assert out.returncode == 2, out
    lines = out.stderr.strip().splitlines()
    assert len(lines) == 1 and "served name" in lines[0], out.stderr


@pytest.mark.parametrize("client", ["*", "**"])
def test_a_wildcard_client_id_gets_no_free_lease(serve, client: str) -> None:
    """Before: an acquire with ``"client": "*"`` and no token of its own was granted: the token lookup took
    the id for a key expression and matched a connected client's token."""
    server: ServeProcess = serve(f"g={sim('wsg50')}")
    honest = grippers.open(server.urls["g"])  # a connected client: its token is there to be matched
    session = _raw_session(server.endpoint)
    try:
        honest.state()
        replies = list(session.get("grippers/g/cmd/control", payload=_acquire(client), timeout=5))
        assert len(replies) == 1 and replies[0].err is not None, replies
        doc = json.loads(replies[0].err.payload.to_bytes())
        assert doc["error"] == "ProtocolError" and "client id" in doc["message"], doc
        with honest.control():  # the lease is still free for a client the server can watch
            honest.home()
    finally:
        session.close()
        honest.close()


def test_a_familys_own_error_crosses_the_wire_as_its_nearest_known_class() -> None:
    """Issue 43 §5: a served Robotiq's fault reached a client as GripperError("RobotiqFault: ...")."""
    from grippers.backends.robotiq import RobotiqFault

    fault = RobotiqFault("gripper fault 0x7: overcurrent", status=7, status_name="OVERCURRENT", device="r")
    error = protocol.decode_error(protocol.encode_error(fault, "move"), "move", "r@zenoh://r")
    assert type(error) is grippers.CommandFailed
    assert (error.status, error.status_name) == (7, "OVERCURRENT") and "overcurrent" in error.message
