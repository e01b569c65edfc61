"""The pure parts: request parsing, errors across the wire, the lease bookkeeping (no Zenoh involved)."""

from __future__ import annotations

import json

import pytest

import grippers
from grippers.remote import protocol
from grippers.remote.lease import MAX_TRACKED, Lease


@pytest.mark.parametrize("name", sorted(protocol.error_classes()))
def test_every_known_error_class_comes_back_as_itself(name: str) -> None:
    cls = protocol.error_classes()[name]
    kwargs = {"holder": "ui"} if name == "AccessDenied" else {}
    if name == "CommandFailed":
        kwargs = {"status": 18, "status_name": "E_CMD_FAILED"}
    exc = cls("it went wrong", device="server-side", command="move", **kwargs)
    back = protocol.decode_error(protocol.encode_error(exc, "move"), "move", "client-side")
    assert type(back) is cls
    assert back.message == "it went wrong" and back.command == "move" and back.device == "client-side"
    for attr, value in kwargs.items():
        assert getattr(back, attr) == value


def test_unknown_and_foreign_errors() -> None:
    doc = json.dumps({"error": "SomethingNew", "message": "m", "command": "move"}).encode()
    back = protocol.decode_error(doc, "move", "dev")
    assert type(back) is grippers.GripperError and "SomethingNew" in str(back)
    bug = protocol.decode_error(protocol.encode_error(KeyError("x"), "move"), "move", "dev")
    assert type(bug) is grippers.GripperError and "server error" in str(bug)
    assert isinstance(protocol.decode_error(b"\x00garbage", "move", "dev"), grippers.ProtocolError)


def test_request_parsing() -> None:
    req = protocol.parse_request("move", protocol.encode_request("c1", "ui", {"width": 0.05}))
    assert req.args == {"width": 0.05, "speed": None, "timeout": None} and req.client == "c1"
    with pytest.raises(grippers.ProtocolError, match="needs the lease"):
        protocol.parse_request("move", b'{"args": {"width": 0.05}}')
    assert protocol.parse_request("stop", b'{"v": 1}').args == {}
    with pytest.raises(grippers.ProtocolError, match="unknown command"):
        protocol.parse_request("explode", b"")
    with pytest.raises(grippers.ProtocolError, match="not JSON"):
        protocol.parse_request("move", b'{"client": "c", "args": {"width": Infinity}}')
    with pytest.raises(grippers.ProtocolError, match="finite"):
        protocol.parse_request("move", b'{"client": "c", "args": {"width": 1e999}}')


@pytest.mark.parametrize("command", sorted(protocol.COMMANDS))
def test_a_query_without_payload_is_never_a_command(command: str) -> None:
    """What `z_get -s 'grippers/**'` sends to every queryable: it fast-stopped every gripper (issue 23)."""
    with pytest.raises(grippers.ProtocolError, match="never a command"):
        protocol.parse_request(command, b"")


@pytest.mark.parametrize("digits", [400, 4000])
def test_a_huge_integer_is_a_protocol_error(digits: int) -> None:
    """JSON integers have no size limit; float() of one this long overflows (issue 23 §3)."""
    payload = b'{"client": "c", "args": {"width": 1' + b"0" * (digits - 1) + b"}}"
    with pytest.raises(grippers.ProtocolError, match="too large"):
        protocol.parse_request("move", payload)


@pytest.mark.parametrize("name", ["a/b", "*", "**", "a$b", "", "x" * 65, "-a", "a?b", "a#b"])
def test_served_names_are_one_plain_key_chunk(name: str) -> None:
    with pytest.raises(ValueError):
        protocol.check_name(name)


def test_lease_bookkeeping() -> None:
    """Issue 30 §1: the lease is a secret, not a name: an id alone takes, keeps and moves nothing."""
    lease = Lease(timeout=1.0)
    with pytest.raises(grippers.AccessDenied, match="liveliness token"):
        lease.check("a", "robot", None, "move", take=True, now=0.0, device="g")  # no token of its own
    lease.client_seen("a")
    secret = lease.check("a", "robot", None, "move", take=True, now=0.0, device="g")
    assert secret is not None and len(secret) == 32  # 128 bits, hexadecimal
    assert lease.check("a", "robot", secret, "move", take=True, now=0.1, device="g") is None
    with pytest.raises(grippers.AccessDenied, match="robot") as denied:
        lease.check("a", "robot", None, "move", take=True, now=0.2, device="g")  # the holder's id alone
    assert denied.value.holder == "robot"
    with pytest.raises(grippers.AccessDenied):
        lease.check("b", "ui", secret, "move", take=True, now=0.2, device="g")  # the secret with another id
    with pytest.raises(grippers.AccessDenied):
        lease.check("a", "robot", "0" * 32, "move", take=True, now=0.2, device="g")  # a guess
    assert lease.expired(0.5) is None
    assert lease.expired(1.5) == "a"  # not heard from with its secret within the timeout: freed
    with pytest.raises(grippers.AccessDenied, match="ended"):
        lease.check("a", "robot", secret, "move", take=True, now=1.6, device="g")  # never a silent re-take
    lease.client_seen("b")
    second = lease.check("b", "ui", None, "home", take=True, now=2.0, device="g")
    assert second is not None and second != secret  # new for every acquisition
    lease.check("b", "ui", second, "move", take=True, now=9.5, device="g")
    assert lease.expired(10.0) is None  # heard from within the timeout: held
    assert lease.expired(10.6) == "b"  # silent longer than the timeout, token or not (issue 23 §2)
    third = lease.check("b", "ui", None, "home", take=True, now=11.0, device="g")
    assert not lease.release("b", None) and not lease.release("b", second)  # only the secret releases
    assert lease.client_gone("b") is True and lease.holder is None  # the token's end frees it (deadman)
    assert lease.client_gone("b") is False and third


def test_the_lease_remembers_a_bounded_number_of_clients() -> None:
    lease = Lease(timeout=1.0)
    for i in range(MAX_TRACKED * 3):
        lease.client_seen(f"c{i}")
    assert len(lease.alive) == MAX_TRACKED


def test_help_and_import_do_not_load_zenoh() -> None:
    import subprocess
    import sys

    code = (
        "import sys, grippers, grippers.errors\n"
        "from grippers.cli import build_parser\n"
        "build_parser().format_help()\n"
        "import grippers.remote.protocol, grippers.remote.lease\n"
        "print('zenoh' in sys.modules)"
    )
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=60)
    assert out.returncode == 0, out.stderr
    assert out.stdout.strip() == "False"


def test_remote_benchmarks_are_registered() -> None:
    import sys
    from pathlib import Path

    repo = Path(__file__).resolve().parents[2]
    if str(repo) not in sys.path:
        sys.path.insert(0, str(repo))
    from benchmarks import run

    assert {8, 9, 10, 12} <= set(run._targets())


def test_zenohs_own_timeout_reply_is_no_answer_not_an_undecodable_one() -> None:
    # A server killed mid-query: Zenoh itself replies with the error payload "Timeout" (seen in CI); the
    # client reports ConnectionLost ("no answer"), never ProtocolError "undecodable error reply".
    assert protocol.is_query_timeout(b"Timeout")
    assert not protocol.is_query_timeout(b'{"error": "GripperTimeout", "message": "Timeout"}')
