"""The ``--json`` documents of the CLI, as pydantic models: one definition gives the JSON Schema (printed by
``python -m grippers.cli.schemas [SCHEMA_ID]``, described in docs/cli.md) and the validator the tests run on
real output.

The CLI writes its documents from plain dicts (pydantic is not imported to print), so these models are the
contract the output is checked against, not the code that produces it. Additive changes keep the ``/1``
schema ids; renaming or removing a field bumps them.
"""

from __future__ import annotations

from typing import Literal

from pydantic import BaseModel, ConfigDict, Field

from grippers.states import GraspName

# The firmware exactly as the API's DeviceInfo.firmware says it (issue 22 §1: one value everywhere): the WSG's
# major.minor1.minor2 with a release candidate's -rcN, the MSG's single software-version number.
FIRMWARE_TEXT = "as grippers' DeviceInfo.firmware: up to three numbers (4.0.1, or 4.0.1-rc2, or 12)"
FIRMWARE_PATTERN = r"^\d+(\.\d+){0,2}(-[0-9A-Za-z.]+)?$"


class _Strict(BaseModel):
    model_config = ConfigDict(extra="forbid", strict=True)


class Location(_Strict):
    """Where a device answered; fields that do not apply to its transport are null."""

    transport: str | None = Field(description="tcp, udp, serial, can or sim")
    host: str | None
    port: int | None
    serial_port: str | None
    interface: str | None = Field(description="python-can interface")
    channel: str | None = Field(description="python-can channel")
    node: int | None = Field(description="the device's node id on a bus; null where it has none")
    profile: str | None = Field(description="sim:// profile name")


class State(_Strict):
    width_mm: float = Field(description="opening width in mm")
    speed_mm_s: float | None = Field(description="finger speed in mm/s; null where the device does not say")
    force_n: float | None = Field(description="grip force in N; null where only a current is reported")
    current_a: float | None = Field(
        description="motor current in A; null where the device does not report it"
    )
    grasp_state: GraspName = Field(description="grippers.GraspState, lower case")
    moving: bool
    referenced: bool = Field(
        description="the jaws know their position (homed or calibrated, as the family calls it)"
    )
    faults: list[str] = Field(description="active faults by name, e.g. fast_stop; empty when none")


class StateError(_Strict):
    error: str


class Limits(_Strict):
    """The limits the library enforces: the profile's, narrowed by what the device reports."""

    min_width_mm: float
    max_width_mm: float
    min_speed_mm_s: float
    max_speed_mm_s: float
    min_force_n: float
    max_force_n: float
    max_current_a: float | None = Field(description="for devices controlled by a current limit; else null")


class SamePort(_Strict):
    """Several families opened a device on one serial port (they speak one protocol): who, and the verdict."""

    answered: list[str] = Field(description="the family URLs that opened a device on this port")
    kept: list[str] = Field(description="those reported as grippers: the one the checks agree on, or all")
    why: str = Field(description="what the families' identity checks (their probe_identity hooks) read back")


class Device(_Strict):
    url: str = Field(description="a URL that opens this gripper with grippers.open() and every command")
    family: str = Field(description="the family: the connection URL's first part (a built-in or a plugin's)")
    vendor: str
    model: str
    profile: str = Field(description="the device profile used")
    firmware: str | None = Field(description=FIRMWARE_TEXT, pattern=FIRMWARE_PATTERN)
    hardware: str | None
    serial: str | None
    location: Location
    state: State | StateError | None
    limits: Limits
    warnings: list[str] = Field(
        default_factory=list,
        description="what the probe assumed or ignored, e.g. a model the device cannot report",
    )
    same_port: SamePort | None = Field(
        default=None, description="only where several families answered on one serial port (issue 40 §4)"
    )


class Miss(_Strict):
    url: str
    location: Location
    reason: str | None


class Skip(_Strict):
    target: str
    reason: str


class ProbeDocument(_Strict):
    """``grippers probe --json``. Exit code 0 iff ``grippers`` is not empty."""

    schema_: Literal["grippers.probe/2"] = Field(alias="schema")
    target: str | None = Field(description="the URL given, null for a machine scan")
    timeout_s: float = Field(description="the per-device timeout used")
    grippers: list[Device]
    others: list[Miss] = Field(description="something answered, but not as a gripper")
    silent: list[Miss] = Field(description="nothing answered, or the transport failed")
    skipped: list[Skip] = Field(description="not tried, and why (e.g. the factory address with --no-network)")


class StateDocument(_Strict):
    """``grippers state --json``; with ``--watch`` one such document per line."""

    schema_: Literal["grippers.state/2"] = Field(alias="schema")
    target: str
    time: float = Field(description="Unix time of the reading")
    state: State
    warnings: list[str] = Field(
        default_factory=list,
        description="what the library assumed (grippers.GripperWarning), e.g. a model it cannot read",
    )


class Info(_Strict):
    family: str
    vendor: str
    model: str
    profile: str
    firmware: str | None = Field(description=FIRMWARE_TEXT, pattern=FIRMWARE_PATTERN)
    hardware: str | None
    serial: str | None
    limits: Limits
    extra: dict[str, object] = Field(description="vendor-specific facts")


class InfoDocument(_Strict):
    schema_: Literal["grippers.info/1"] = Field(alias="schema")
    target: str
    info: Info
    warnings: list[str] = Field(
        default_factory=list,
        description="what the library assumed (grippers.GripperWarning), e.g. a model it cannot read",
    )


class MotionOutcome(_Strict):
    width_mm: float
    grasp_state: GraspName


class GraspOutcome(_Strict):
    grasped: bool
    width_mm: float
    force_n: float | None = Field(
        description="grip force reached (estimated from the current where the device reports no force)"
    )
    grasp_state: GraspName
    reason: str | None = Field(description="why no part is held, when none is")


class ResultDocument(_Strict):
    """``grippers home|move|grasp|release|stop|ack --json``."""

    schema_: Literal["grippers.result/2"] = Field(alias="schema")
    command: Literal["home", "move", "grasp", "release", "stop", "ack"]
    target: str
    ok: bool = Field(description="false only for a grasp that gripped no part (exit code 1)")
    result: MotionOutcome | GraspOutcome | None = Field(
        description="move/release: MotionOutcome; grasp: GraspOutcome; home, stop, ack: null"
    )
    state: State | None = Field(description="the state read back after the command")
    warnings: list[str] = Field(
        default_factory=list,
        description="what the library assumed (grippers.GripperWarning), e.g. a model it cannot read",
    )


class MonitorRecord(_Strict):
    """``grippers monitor --json``: one per line, per decoded frame or packet (the family's dissector's)."""

    schema_: Literal["grippers.monitor/1"] = Field(alias="schema")
    time: float | None
    protocol: str = Field(
        description="the family dissector's protocol (its name, e.g. a family's); can: a frame no "
        "family reads (error, extended, CAN FD) or that did not decode"
    )
    direction: str = Field(description="host->gripper, gripper->host or ?")
    id: str | None = Field(
        description="the frame's or packet's id as the family writes it (a command id, a CAN id in hex)"
    )
    node: int | None = Field(
        description="the bus node the frame is for or from; null where the protocol has none"
    )
    command: str | None = Field(description="the command's name in the drivers' table; null for noise")
    fields: dict[str, object] = Field(description="decoded fields in the device's units")
    status: str | None = Field(
        description="a reply's status name where the protocol has one; 'noise', 'error', or a "
        "checksum/length problem; else null"
    )
    text: str = Field(description="the drivers' one-line description, as the text output shows it")
    raw: str | None = Field(description="the packet or frame data in hex; 'R' for a remote frame")


class ProfileSummary(_Strict):
    name: str
    family: str
    vendor: str
    model: str
    aliases: list[str]
    stroke_mm: float
    max_force_n: float
    url: str = Field(description="the profile's default connection URL")
    path: str | None = Field(description="the file it was read from")


class Validation(_Strict):
    file: str
    valid: bool
    problems: list[str] = Field(description="one line each: file, field and rule")


class ProfilesDocument(_Strict):
    """``grippers profiles list|show|validate|path --json``: exactly one of the optional members is set."""

    schema_: Literal["grippers.profiles/1"] = Field(alias="schema")
    profiles: list[ProfileSummary] | None = None
    profile: dict[str, object] | None = Field(default=None, description="the whole profile, as in its file")
    validation: list[Validation] | None = None
    search_path: list[str] | None = None
    skipped: list[Validation] | None = Field(
        default=None, description="with profiles (list): files on the search path that do not validate"
    )


class SettingsDocument(_Strict):
    """``grippers settings URL --json``."""

    schema_: Literal["grippers.settings/1"] = Field(alias="schema")
    target: str
    family: str
    settings: dict[str, object] = Field(
        description="device units in the names (temperature_c, acceleration_mm_s2, force_limit_n, "
        "soft_limits {min_mm, max_mm}, device_tag, finger_N {type, data_size}, node_id, supply_v: what "
        "the family's settings hook reads); "
        "a value the device did not give is {unavailable: why}"
    )
    changed: list[str] = Field(description="the settings this call changed")
    url: str = Field(description="the URL that opens the gripper now (a new node id changes it)")


class DoctorCheck(_Strict):
    name: str = Field(description="what was checked, e.g. 'socketcan can0', 'serial /dev/ttyUSB0'")
    status: Literal["ok", "warn", "fail"]
    detail: str
    fix: str | None = Field(description="the command or step that fixes a warn or fail")
    see: str | None = Field(
        default=None,
        description="for a warn or fail: the section of docs/troubleshooting.md that explains it",
    )


class DoctorDocument(_Strict):
    """``grippers doctor --json``. Exit code 1 iff a check failed (``ok`` false)."""

    schema_: Literal["grippers.doctor/1"] = Field(alias="schema")
    ok: bool
    checks: list[DoctorCheck]


class SimDocument(_Strict):
    """``grippers sim FAMILY --json``: where the simulator (or a replay) serves, printed once at start."""

    schema_: Literal["grippers.sim/1"] = Field(alias="schema")
    what: str = Field(description="what is served, e.g. 'simulated MODEL (firmware X.Y.Z)'")
    urls: list[str] = Field(description="the URLs a client opens, one per simulated device")


class ServedGripper(_Strict):
    name: str
    model: str
    target: str = Field(description="what serve opened (a URL)")
    url: str = Field(description="the zenoh:// URL clients open")


class ServeDocument(_Strict):
    """``grippers serve ... --json``: what is served where, printed once when serving starts."""

    schema_: Literal["grippers.serve/1"] = Field(alias="schema")
    grippers: list[ServedGripper]
    panel: str | None = Field(None, description="the panel's address, with --http (docs/panel.md)")


class PlottedRecording(_Strict):
    recording: str
    grippers: list[str]
    states: int
    cut: str | None = Field(description="why a file cut short was read only up to its last complete row")


class PlotDocument(_Strict):
    """``grippers plot FILE -o IMAGE --json``: what was drawn from what."""

    schema_: Literal["grippers.plot/1"] = Field(alias="schema")
    recording: str
    output: str
    states: int
    commands: int
    recordings: list[PlottedRecording] = Field(default=[], description="what was read from each file")


class SelftestLine(_Strict):
    check: str = Field(description="what was checked, e.g. 'speed 20 mm/s', 'home (2nd)'")
    measured: str
    expected: str = Field(description="the profile's value, or the library's bound")
    verdict: Literal["PASS", "WARN", "INFO"]
    note: str
    value: float | None = Field(description="the measured number (mm, mm/s or s as in check), if any")


class SelftestDocument(_Strict):
    """``grippers selftest URL --json``. Exit code 3 iff a line is a WARN (``ok`` false)."""

    schema_: Literal["grippers.selftest/1"] = Field(alias="schema")
    target: str
    family: str
    profile: str
    time_scale: float
    tolerance: float
    lines: list[SelftestLine]
    warnings: int
    ok: bool
    written_profile: str | None = Field(description="the --write-profile file, when written")


class RecordedGripper(_Strict):
    name: str
    target: str


class RecordResultDocument(_Strict):
    """``grippers record ... --json``: what was recorded where (the files' header is grippers.record/2)."""

    schema_: Literal["grippers.record-result/1"] = Field(alias="schema")
    target: str = Field(description="the URLs recorded, separated by spaces")
    grippers: list[RecordedGripper] = Field(default=[], description="each gripper's name in the file")
    output: str
    format: Literal["csv", "jsonl", "mcap"]
    files: list[str] = Field(description="every file written: a CSV's header goes to FILE.csv.json")
    states: int
    command_events: int
    failed: str | None = Field(description="the error of the --do command that failed, if one did")


SCHEMAS: dict[str, type[BaseModel]] = {
    "grippers.probe/2": ProbeDocument,
    "grippers.state/2": StateDocument,
    "grippers.info/1": InfoDocument,
    "grippers.result/2": ResultDocument,
    "grippers.monitor/1": MonitorRecord,
    "grippers.profiles/1": ProfilesDocument,
    "grippers.settings/1": SettingsDocument,
    "grippers.doctor/1": DoctorDocument,
    "grippers.sim/1": SimDocument,
    "grippers.serve/1": ServeDocument,
    "grippers.plot/1": PlotDocument,
    "grippers.selftest/1": SelftestDocument,
    "grippers.record-result/1": RecordResultDocument,
}


def validate(document: dict) -> BaseModel:
    """Check a document against the schema its ``schema`` field names; raises pydantic's ValidationError."""
    model = SCHEMAS[document["schema"]]
    return model.model_validate(document)


def json_schema(schema_id: str) -> dict:
    return SCHEMAS[schema_id].model_json_schema(by_alias=True)


if __name__ == "__main__":  # python -m grippers.cli.schemas [grippers.probe/2 ...]
    import json
    import sys

    unknown = [name for name in sys.argv[1:] if name not in SCHEMAS]
    if unknown:  # one line, as every CLI error: no KeyError traceback
        known = ", ".join(SCHEMAS)
        sys.exit(f"python -m grippers.cli.schemas: error: unknown schema {unknown[0]!r} (known: {known})")
    for schema_id in sys.argv[1:] or list(SCHEMAS):
        print(json.dumps(json_schema(schema_id), indent=2))
