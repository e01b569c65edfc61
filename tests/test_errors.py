"""The exception hierarchy users catch: each error is also the built-in they already handle."""

from __future__ import annotations

import pytest

from grippers.drivers.errors import (
    CommandFailed,
    ConnectionLost,
    GripperError,
    GripperTimeout,
    LimitError,
    NotSupported,
    ProtocolError,
)


@pytest.mark.parametrize(
    ("cls", "builtin"),
    [(GripperTimeout, TimeoutError), (ConnectionLost, ConnectionError), (LimitError, ValueError)],
)
def test_errors_are_also_builtins(cls: type[GripperError], builtin: type[Exception]) -> None:
    err = cls("no reply", device="wsg+tcp://127.0.0.1:1000", command="GET_WIDTH")
    assert isinstance(err, builtin)
    assert isinstance(err, GripperError)


def test_message_names_device_command_and_cause() -> None:
    err = CommandFailed(
        "device refused",
        status=16,
        status_name="E_ACCESS_DENIED",
        device="wsg50@127.0.0.1",
        command="PREPOSITION",
    )
    assert str(err) == "wsg50@127.0.0.1: PREPOSITION: device refused"
    assert (err.status, err.status_name) == (16, "E_ACCESS_DENIED")


@pytest.mark.parametrize("cls", [NotSupported, ProtocolError])
def test_message_without_context(cls: type[GripperError]) -> None:
    assert str(cls("bad frame")) == "bad frame"
