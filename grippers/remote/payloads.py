"""API objects to and from the JSON documents of docs/remote.md (SI units, the field names of the API)."""

from __future__ import annotations

import math
from typing import Any

from ..errors import ProtocolError
from ..gripper import DeviceInfo, GraspResult, GraspState, GripperState, MotionResult
from ..profiles import Limits
from .protocol import PROTOCOL_VERSION


def _opt(value: float | None) -> float | None:
    return None if value is None or not math.isfinite(value) else float(value)


def state_doc(state: GripperState, seq: int) -> dict[str, Any]:
    return {
        "v": PROTOCOL_VERSION,
        "seq": seq,
        "timestamp": state.timestamp,
        "width": state.width,
        "speed": _opt(state.speed),
        "force": _opt(state.force),
        "current": _opt(state.current),
        "grasp": state.grasp.value,
        "moving": state.moving,
        "referenced": state.referenced,
        "faults": list(state.faults),
    }


def state_from(doc: Any, device: str) -> tuple[int, GripperState]:
    try:
        return int(doc["seq"]), GripperState(
            width=float(doc["width"]),
            speed=None if doc["speed"] is None else float(doc["speed"]),
            force=None if doc["force"] is None else float(doc["force"]),
            current=None if doc["current"] is None else float(doc["current"]),
            grasp=GraspState(doc["grasp"]),
            moving=bool(doc["moving"]),
            referenced=bool(doc["referenced"]),
            faults=tuple(str(f) for f in doc["faults"]),
            timestamp=float(doc["timestamp"]),
        )
    except (KeyError, TypeError, ValueError) as exc:
        raise ProtocolError(f"malformed state document: {exc!r}", device=device, command="state") from None


def motion_doc(result: MotionResult) -> dict[str, Any]:
    return {"width": result.width, "state": result.state.value}


def grasp_doc(result: GraspResult) -> dict[str, Any]:
    return {
        "grasped": result.grasped,
        "width": result.width,
        "force": _opt(result.force),
        "state": result.state.value,
        "reason": result.reason,
    }


def result_doc(value: Any) -> Any:
    if isinstance(value, GraspResult):
        return grasp_doc(value)
    if isinstance(value, MotionResult):
        return motion_doc(value)
    if value is None or isinstance(value, str | int | float | bool):
        return value
    return str(value)


def motion_from(doc: Any, device: str, command: str) -> MotionResult:
    try:
        return MotionResult(width=float(doc["width"]), state=GraspState(doc["state"]))
    except (KeyError, TypeError, ValueError) as exc:
        raise ProtocolError(f"malformed result: {exc!r}", device=device, command=command) from None


def grasp_from(doc: Any, device: str) -> GraspResult:
    try:
        return GraspResult(
            grasped=bool(doc["grasped"]),
            width=float(doc["width"]),
            force=None if doc["force"] is None else float(doc["force"]),
            state=GraspState(doc["state"]),
            reason=doc.get("reason"),
        )
    except (KeyError, TypeError, ValueError) as exc:
        raise ProtocolError(f"malformed grasp result: {exc!r}", device=device, command="grasp") from None


def info_doc(
    name: str,
    info: DeviceInfo,
    capabilities: list[str],
    profile_data: dict[str, Any],
    lease_timeout: float | None = None,
    profile_assumed: bool = False,
) -> dict[str, Any]:
    """Everything a client needs to check limits locally and to rebuild the profile it was served with.

    ``profile_assumed``: the served gripper's model was guessed (an MSG opened without a profile), so a
    ``zenoh://`` client warns at open as a local one does (issue 22 §1)."""
    return {
        "v": PROTOCOL_VERSION,
        "name": name,
        "family": info.family,
        "vendor": info.vendor,
        "model": info.model,
        "serial": info.serial,
        "firmware": info.firmware,
        "hardware": info.hardware,
        "url": info.url,
        "profile": info.profile,
        "limits": info.limits.model_dump(mode="json"),
        "capabilities": capabilities,
        "extra": {str(k): _plain(v) for k, v in info.extra.items()},
        "profile_data": profile_data,
        "lease_timeout": lease_timeout,
        "profile_assumed": profile_assumed,
    }


def _plain(value: Any) -> Any:
    if value is None or isinstance(value, str | bool | int):
        return value
    if isinstance(value, float):
        return value if math.isfinite(value) else None
    if isinstance(value, dict):
        return {str(k): _plain(v) for k, v in value.items()}
    if isinstance(value, list | tuple):
        return [_plain(v) for v in value]
    if hasattr(value, "value"):  # an enum
        return _plain(value.value)
    return str(value)


def info_from(doc: Any, url: str, device: str) -> DeviceInfo:
    try:
        return DeviceInfo(
            family=str(doc["family"]),
            vendor=str(doc["vendor"]),
            model=str(doc["model"]),
            serial=doc["serial"],
            firmware=doc["firmware"],
            hardware=doc["hardware"],
            limits=Limits.model_validate(doc["limits"]),
            url=url,
            profile=str(doc["profile"]),
            extra={**doc.get("extra", {}), "served_url": doc["url"], "served_name": doc["name"]},
        )
    except (KeyError, TypeError, ValueError) as exc:
        raise ProtocolError(f"malformed info document: {exc!r}", device=device, command="info") from None
