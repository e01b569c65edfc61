"""The Modbus example of docs/backend-kit.md runs as printed: a ```python block followed by a plain ```
block of what it prints (the README's convention, tests/cli/test_readme_examples.py)."""

from __future__ import annotations

import re
import subprocess
import sys
from pathlib import Path

KIT_MD = Path(__file__).resolve().parents[2] / "docs" / "backend-kit.md"


def _examples() -> list[tuple[str, str]]:
    section = KIT_MD.read_text().partition("\n## Modbus\n")[2].partition("\n## ")[0]
    block = r"((?:(?!```).)*)"  # a block's text: anything up to the next fence
    return re.findall(rf"```python\n{block}```\n\n```\n{block}```", section, re.DOTALL)


def test_the_modbus_example_runs_as_printed() -> None:
    examples = _examples()
    assert len(examples) == 1, "the Modbus section's example and its output were not found"
    code, printed = examples[0]
    done = subprocess.run(
        [sys.executable, "-c", code], capture_output=True, text=True, timeout=120, cwd=KIT_MD.parent
    )
    assert done.returncode == 0, done.stderr
    assert done.stdout == printed
