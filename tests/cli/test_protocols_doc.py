"""Issue 16 §6: the project carries its own protocol reference. Every `docs/protocols.md §N "Name"` citation
in the repository points at a section that exists; nothing in the CLI cites a file outside the repo."""

from __future__ import annotations

import re
from pathlib import Path

ROOT = Path(__file__).resolve().parents[2]
DOC = ROOT / "docs" / "protocols.md"
CITATION = re.compile(r'docs/protocols\.md §(\d+)(?: "([^"]+)")?')


def _sections() -> dict[str, set[str]]:
    sections: dict[str, set[str]] = {}
    current = None
    for line in DOC.read_text().splitlines():
        m = re.match(r"## (\d+)\. ", line)
        if m:
            current = m.group(1)
            sections[current] = set()
        elif line.startswith("### ") and current:
            sections[current].add(line[4:].strip())
    return sections


def _files() -> list[Path]:
    out = []
    for pattern in ("*.py", "*.md", "*.toml"):
        out += [p for p in ROOT.rglob(pattern) if ".venv" not in p.parts and "site-packages" not in str(p)]
    return out


def test_sections_one_and_two_with_their_subsections() -> None:
    sections = _sections()
    assert {"1", "2"} <= set(sections)
    assert "Framing and checksum" in sections["1"]
    assert any(h.startswith("Transport defaults") for h in sections["1"])
    assert {
        "CAN",
        "Firmware behaviour a client must survive (read in the STEPFOC firmware source)",
        "UART text interface",
    } <= sections["2"]


def test_every_citation_resolves() -> None:
    sections = _sections()
    bad = []
    for path in _files():
        for m in CITATION.finditer(path.read_text(errors="replace")):
            number, name = m.group(1), m.group(2)
            if name:  # a citation wrapped across lines (of a docstring or of # comments)
                name = " ".join(w for w in name.split() if w != "#")
            if number not in sections:
                bad.append(f"{path.relative_to(ROOT)}: §{number}")
            elif name and not any(h.startswith(name) for h in sections[number]):
                bad.append(f'{path.relative_to(ROOT)}: §{number} "{name}"')
    assert not bad, bad


def test_nothing_cites_a_file_outside_the_repository() -> None:
    """The project carries what it relies on: code, profiles and docs cite docs/protocols.md, not the notes it
    was first gathered in (a file outside the repository)."""
    cited = [p for p in _files() if "PROTOCOL-NOTES" in p.read_text(errors="replace") and p != Path(__file__)]
    assert not cited, cited
