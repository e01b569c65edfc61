"""A TOML writer for plain data (what ``profiles show`` prints), so that the printed profile is a file that
``profiles validate`` accepts and that loads back to the same profile.

The standard library reads TOML (tomllib) but does not write it; a profile is small and regular (tables of
scalars and lists), so a few rules of the TOML 1.0 specification (https://toml.io/en/v1.0.0) suffice: keys
bare when they can be, basic strings with JSON-compatible escapes, ``inf``/``nan`` spelled as TOML spells
them, ``None`` left out (TOML has no null; a left-out field takes its default).
"""

from __future__ import annotations

import json
import math
import re
from collections.abc import Mapping
from typing import Any

_BARE_KEY = re.compile(r"^[A-Za-z0-9_-]+$")


def _key(name: str) -> str:
    return name if _BARE_KEY.match(name) else json.dumps(name, ensure_ascii=False)


def _value(value: Any) -> str:
    if isinstance(value, bool):
        return "true" if value else "false"
    if isinstance(value, int):
        return str(value)
    if isinstance(value, float):
        if math.isnan(value):
            return "nan"
        if math.isinf(value):
            return "inf" if value > 0 else "-inf"
        return repr(value)
    if isinstance(value, str):
        return json.dumps(value, ensure_ascii=False)  # a JSON string is a TOML basic string
    if isinstance(value, list | tuple):
        return "[" + ", ".join(_value(v) for v in value if v is not None) + "]"
    if isinstance(value, Mapping):  # an inline table, for a mapping inside a list
        items = ", ".join(f"{_key(str(k))} = {_value(v)}" for k, v in value.items() if v is not None)
        return "{" + items + "}"
    raise TypeError(f"no TOML form for {type(value).__name__}")


def dumps(document: Mapping[str, Any]) -> str:
    """``document`` as TOML: its scalars first, then one ``[table]`` per nested mapping."""
    lines: list[str] = []
    _table(document, (), lines)
    return "\n".join(lines).strip("\n") + "\n"


def _table(table: Mapping[str, Any], path: tuple[str, ...], lines: list[str]) -> None:
    scalars = [(k, v) for k, v in table.items() if v is not None and not isinstance(v, Mapping)]
    tables = [(k, v) for k, v in table.items() if isinstance(v, Mapping)]
    if path and (scalars or not tables):
        lines.append("")
        lines.append("[" + ".".join(_key(p) for p in path) + "]")
    for key, value in scalars:
        lines.append(f"{_key(str(key))} = {_value(value)}")
    for key, value in tables:
        _table(value, (*path, str(key)), lines)
