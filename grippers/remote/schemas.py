"""JSON Schemas of the served payloads (docs/remote.md), as pydantic models: one definition gives the schema
(``python -m grippers.remote.schemas [NAME ...]``) and the validator the tests run on real payloads, so a
client written in another language has a contract to read. The server writes its payloads from plain dicts
(protocol.py, payloads.py); these models check them. Additive changes keep version 1.
"""

from __future__ import annotations

from typing import Literal

from pydantic import BaseModel, ConfigDict, Field

from grippers.states import GraspName


class _Strict(BaseModel):
    model_config = ConfigDict(extra="forbid")


class State(_Strict):
    """``grippers/<name>/state``: published at the server's rate and on every change; also the reply to a
    query on the same key (the latest reading)."""

    v: Literal[1]
    seq: int = Field(ge=1, description="publication number, +1 each; a gap means publications were lost")
    timestamp: float = Field(description="seconds since the Unix epoch when the state was read")
    width: float = Field(description="m")
    speed: float | None = Field(description="m/s; null where the device does not report it")
    force: float | None = Field(description="N; null where only a current is reported")
    current: float | None = Field(description="A; null where the device does not report it")
    grasp: GraspName = Field(description="grippers.GraspState")
    moving: bool
    referenced: bool = Field(description="homed, calibrated or activated, as the family does: home() done")
    faults: list[str] = Field(description="active faults by name (fast_stop, ...)")


class Limits(_Strict):
    min_width: float
    max_width: float
    min_speed: float
    max_speed: float
    min_force: float
    max_force: float
    max_current: float | None


class Info(_Strict):
    """``grippers/<name>/info``: identity, effective limits (SI) and capabilities of the served gripper."""

    v: Literal[1]
    name: str
    family: str
    vendor: str
    model: str
    serial: str | None
    firmware: str | None
    hardware: str | None
    url: str = Field(description="the URL the server opened the gripper with")
    profile: str
    limits: Limits
    capabilities: list[str]
    extra: dict[str, object]
    profile_data: dict[str, object] = Field(description="the served profile, as a profile file holds it")
    lease_timeout: float | None = Field(
        default=None,
        description="s: the server's --lease-timeout; a holder sends control heartbeat with its lease "
        "secret at least this often (a quarter of it is what zenoh:// clients do)",
    )
    refused: int = Field(
        default=0, description="requests refused for want of the lease secret since the server started"
    )
    profile_assumed: bool = Field(
        default=False,
        description="the served gripper's model was assumed (a device that cannot report it, opened "
        "without a profile): clients warn",
    )


class Request(_Strict):
    """The payload of a query on ``grippers/<name>/cmd/<command>``."""

    v: Literal[1] = 1
    client: str = Field(
        default="", max_length=128, description="the id in the caller's token grippers/<name>/client/<id>"
    )
    label: str = Field(default="", max_length=256, description="who the caller is, for AccessDenied messages")
    lease: str | None = Field(
        default=None,
        pattern="^[0-9a-f]{1,64}$",
        description="the lease secret the server answered when this client took the lease; required on "
        "every command that needs the lease and on control heartbeat while it is held",
    )
    args: dict[str, float | str | None] = Field(default_factory=dict, description="SI units")


class Reply(_Strict):
    """A successful reply: motions answer ``pending`` at once, then ``done``; other commands ``done``."""

    v: Literal[1]
    status: Literal["pending", "done"]
    result: dict[str, object] | float | str | None
    lease: str | None = Field(
        default=None,
        description="the lease secret, in the one reply to the request that took the lease (control "
        "acquire, or the first reply of a motion on a free lease): keep it, send it with every command",
    )


class Error(_Strict):
    """An error reply (Zenoh ``reply_err``): the exception class's name, its message, the command."""

    v: Literal[1]
    error: str = Field(description="GripperError, LimitError, AccessDenied, ... (unknown: GripperError)")
    message: str
    command: str
    device: str | None = None
    status: int | None = None
    status_name: str | None = None
    holder: str | None = None


SCHEMAS: dict[str, type[BaseModel]] = {
    "grippers.remote.state/1": State,
    "grippers.remote.info/1": Info,
    "grippers.remote.request/1": Request,
    "grippers.remote.reply/1": Reply,
    "grippers.remote.error/1": Error,
}


def json_schema(schema_id: str) -> dict:
    return SCHEMAS[schema_id].model_json_schema()


if __name__ == "__main__":  # python -m grippers.remote.schemas [grippers.remote.state/1 ...]
    import json
    import sys

    for schema_id in sys.argv[1:] or list(SCHEMAS):
        print(json.dumps(json_schema(schema_id), indent=2))
