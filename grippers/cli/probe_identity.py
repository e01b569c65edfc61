"""Several families answering on one serial port (issue 40 §4): each family's identity check decides.

Two families that speak one protocol (a plugin on Robotiq's register map, Modbus RTU) both open a device
on a bare serial port. The probe then tries every candidate of that protocol there (their
``ProbeCandidate.protocol``), asks each family that answered its ``probe_identity(gripper)`` hook while the
device is open, and keeps the device the checks agree on; the output says who answered and why one was
kept (``same_port`` in the JSON, a line in the text). No global order decides: where no check tells the
answers apart, all of them are reported.
"""

from __future__ import annotations

from typing import Any


def identity_of(url: str, gripper: Any) -> dict[str, Any] | None:
    """The family's ``probe_identity`` verdict on an opened device, or None when the family has no check."""
    from grippers.backends import find_backend
    from grippers.backends.command_hooks import commands_of

    try:
        said = commands_of(find_backend(url.partition("+")[0])).probe_identity(gripper)
    except Exception as exc:  # a check that cannot read is no verdict, and no reason to lose the device
        return {"mine": None, "reason": f"its identity check failed: {exc}"}
    if said is None:
        return None
    return {"mine": said.mine, "reason": said.reason}


def _family(outcome: Any) -> str:
    return str(outcome.url.partition("+")[0])


def _said(outcome: Any) -> str:
    identity = outcome.identity
    return f"{_family(outcome)}: {identity['reason'] if identity else 'no identity check'}"


def choose(answered: list[Any]) -> tuple[list[Any], str]:
    """The outcomes kept among those that answered on one port, and why."""

    def verdict(o: Any) -> bool | None:
        return (o.identity or {}).get("mine")

    mine = [o for o in answered if verdict(o) is True]
    if len(mine) == 1:
        return mine, f"identified by {_said(mine[0])}"
    refused = [o for o in answered if verdict(o) is False]
    left = mine or [o for o in answered if o not in refused]
    if len(left) == 1:
        return left, "the other families' checks refused it (" + "; ".join(map(_said, refused)) + ")"
    kept = left or answered
    return kept, "no identity check told them apart (" + "; ".join(map(_said, answered)) + "): all reported"


def resolve(outcomes: list[Any], group_of: dict[str, str]) -> list[Any]:
    """``outcomes`` with one decision per shared resource where several families answered: the kept ones
    carry ``same_port`` in their device, the others become "answered, not this family's" outcomes."""
    by_group: dict[str, list[Any]] = {}
    for o in outcomes:
        if o.kind == "gripper" and o.device is not None:
            by_group.setdefault(group_of.get(o.url, o.url), []).append(o)
    for answered in by_group.values():
        if len(answered) < 2:
            continue
        kept, why = choose(answered)
        urls = [o.url for o in answered]
        for o in answered:
            if o in kept:
                o.device["same_port"] = {"answered": urls, "kept": [k.url for k in kept], "why": why}
            else:
                o.kind, o.device = "other", None
                o.reason = f"answered too, but not as its family's device ({_said(o)}); kept: {kept[0].url}"
    return outcomes
