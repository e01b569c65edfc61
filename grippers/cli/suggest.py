"""The right spelling for a mistyped target, added to the one-line error (issue 16 §6).

Pure string work over the families, transports and profile names the library knows, so each rule is tested
on strings. A suggestion is only offered when it is a target the command accepts as written.
"""

from __future__ import annotations

import difflib
import ipaddress
import re
from collections.abc import Iterable, Mapping, Sequence

TRANSPORTS = ("tcp", "udp", "serial", "can")
# The suffixes grippers.profiles reads (PROFILE_SUFFIXES; not imported: this module must not load pydantic).
PROFILE_FILES = (".toml", ".yaml", ".yml", ".json")
Forms = Mapping[str, Sequence[str]]  # bare transport -> the family URL forms to offer ("wsg+tcp://{rest}")


def bare_forms() -> dict[str, list[str]]:
    """What a bare transport carries, from every installed family's backend (its ``bare_forms``: transport ->
    (rank, form)), best-ranked first: the family URLs to suggest for ``tcp://HOST`` and the like."""
    from grippers.backends import available_backends, find_backend
    from grippers.backends.command_hooks import commands_of

    ranked: dict[str, list[tuple[int, str]]] = {}
    for family in available_backends():
        try:
            forms = commands_of(find_backend(family)).bare_forms()
        except Exception:  # a family whose optional dependency is missing: no hint from it
            continue
        for transport, (rank, form) in forms.items():
            ranked.setdefault(transport, []).append((rank, form))
    return {t: [form for _rank, form in sorted(items)] for t, items in ranked.items()}


def _looks_like_host(text: str) -> bool:
    host, _, port = text.rpartition(":") if text.count(":") == 1 else (text, "", "")
    if port and not port.isdigit():
        return False
    try:
        ipaddress.ip_address(host)
        return True
    except ValueError:
        return bool(re.fullmatch(r"[A-Za-z0-9-]+(\.[A-Za-z0-9-]+)+", host))


def suggest(
    target: str, families: Iterable[str], profiles: Iterable[str], bare: Forms | None = None
) -> str | None:
    """A corrected target for ``target``, or None when nothing close is known; ``bare``: the family URL
    forms each bare transport carries (:func:`bare_forms`)."""
    bare = bare or {}
    families = list(families)
    profiles = list(profiles)
    text = target.strip()
    scheme, sep, rest = text.partition("://")
    if not sep:
        m = re.fullmatch(r"([A-Za-z][A-Za-z0-9+]*):/*(.+)", text)
        if m and (m[1].lower() in TRANSPORTS or "+" in m[1] or m[1].lower() == "sim"):
            return (
                suggest(f"{m[1]}://{m[2]}", families, profiles, bare) or f"{m[1]}://{m[2]}"
            )  # wsg+tcp:/host
        if text.lower().endswith(PROFILE_FILES):
            return None  # a profile file's name (nope.toml): its own error says "not found", not a host
        if text.startswith("/dev/"):  # a bare serial port (issue 39 §2): each family's serial URL
            return " or ".join(form.format(rest=text) for form in bare.get("serial", ())) or None
        if _looks_like_host(text) and bare.get("tcp"):
            return bare["tcp"][0].format(rest=text)  # a bare address: the first family on Ethernet
        if text in profiles:
            return None
        close = difflib.get_close_matches(text, profiles, n=1, cutoff=0.6)
        return close[0] if close else None
    scheme = scheme.lower()
    if scheme == "sim":
        name = rest.split("?", 1)[0].strip("/")
        if name and name not in profiles:
            close = difflib.get_close_matches(name, profiles, n=1, cutoff=0.6)
            if close:
                return f"sim://{close[0]}" + (f"?{rest.split('?', 1)[1]}" if "?" in rest else "")
        return None
    if scheme in TRANSPORTS:
        return " or ".join(form.format(rest=rest) for form in bare.get(scheme, ())) or None
    family, plus, transport = scheme.partition("+")
    if plus:
        fixed_family = (
            family
            if family in families
            else next(iter(difflib.get_close_matches(family, families, n=1, cutoff=0.5)), None)
        )
        fixed_transport = (
            transport
            if transport in TRANSPORTS
            else next(iter(difflib.get_close_matches(transport, TRANSPORTS, n=1, cutoff=0.5)), None)
        )
        if fixed_family and fixed_transport and (fixed_family, fixed_transport) != (family, transport):
            return f"{fixed_family}+{fixed_transport}://{rest}"
    return None


def hint(target: str) -> str | None:
    """``did you mean …?`` for the error line, from the installed families and the profiles found."""
    try:
        from grippers.backends import available_backends
        from grippers.profiles import list_profiles

        names: list[str] = []
        for profile in list_profiles():
            names.append(profile.name)
            names.extend(profile.aliases)
        fixed = suggest(target, available_backends(), names, bare_forms())
    except Exception:  # a hint must never replace the error it decorates
        return None
    return None if fixed is None or fixed == target else f"did you mean {fixed}?"
