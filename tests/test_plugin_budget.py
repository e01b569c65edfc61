"""What a plugin costs (issue 40 §2): the worked example ``examples/acme_r1`` stays within 250 lines of
gripper-specific code (everything but its codec and simulator) and 40 lines of command hooks (its
``CommandHooks`` subclass), counted as code lines: blank lines, comments and docstrings left out, every
other physical line of the formatted source counted (an import wrapped over five lines is five).

Run as a script, it prints the counts::

    python tests/test_plugin_budget.py
"""

from __future__ import annotations

import ast
import io
import tokenize
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent
PACKAGE = ROOT / "examples" / "acme_r1" / "acme_r1"
NOT_COUNTED = {"codec.py", "sim.py"}  # the wire format and the simulator: every family has them, apart
CODE_BUDGET = 250
HOOKS_BUDGET = 40
_NOT_CODE = {
    tokenize.COMMENT,
    tokenize.NL,
    tokenize.NEWLINE,
    tokenize.INDENT,
    tokenize.DEDENT,
    tokenize.ENCODING,
    tokenize.ENDMARKER,
}


def _docstring_lines(tree: ast.AST) -> set[int]:
    lines: set[int] = set()
    for node in ast.walk(tree):
        if isinstance(node, ast.Module | ast.ClassDef | ast.FunctionDef | ast.AsyncFunctionDef):
            first = node.body[0] if node.body else None
            if (
                isinstance(first, ast.Expr)
                and isinstance(first.value, ast.Constant)
                and isinstance(first.value.value, str)
            ):
                lines.update(range(first.lineno, (first.end_lineno or first.lineno) + 1))
    return lines


def code_lines(source: str) -> set[int]:
    """The numbers of the lines of ``source`` that hold code (not blank, comment or docstring)."""
    lines: set[int] = set()
    for token in tokenize.tokenize(io.BytesIO(source.encode()).readline):
        if token.type not in _NOT_CODE:
            lines.update(range(token.start[0], token.end[0] + 1))
    return lines - _docstring_lines(ast.parse(source))


def hooks_lines(source: str) -> set[int]:
    """The code lines of the classes that subclass ``CommandHooks``."""
    spans: set[int] = set()
    for node in ast.walk(ast.parse(source)):
        if isinstance(node, ast.ClassDef) and any(
            isinstance(base, ast.Name) and base.id == "CommandHooks" for base in node.bases
        ):
            first = min([node.lineno, *(d.lineno for d in node.decorator_list)])
            spans.update(range(first, (node.end_lineno or node.lineno) + 1))
    return code_lines(source) & spans


def counts() -> dict[str, int]:
    """Code lines per counted file, the total, and the command hooks' lines."""
    out: dict[str, int] = {}
    hooks = 0
    for path in sorted(PACKAGE.rglob("*.py")):
        if path.name in NOT_COUNTED:
            continue
        source = path.read_text(encoding="utf-8")
        out[str(path.relative_to(ROOT))] = len(code_lines(source))
        hooks += len(hooks_lines(source))
    out["total"] = sum(out.values())
    out["command hooks"] = hooks
    return out


def test_the_counter_drops_blanks_comments_and_docstrings() -> None:
    source = (
        '"""Module."""\n\nimport os  # why\n\n\n'
        'class A(CommandHooks):\n    """Doc,\n    two lines."""\n\n    x = (\n        1\n    )\n'
    )
    assert sorted(code_lines(source)) == [3, 6, 10, 11, 12]
    assert sorted(hooks_lines(source)) == [6, 10, 11, 12]


def test_the_worked_plugin_stays_within_its_budget() -> None:
    found = counts()
    assert found["command hooks"] > 0, "no CommandHooks subclass found: the count would mean nothing"
    assert found["total"] <= CODE_BUDGET, found
    assert found["command hooks"] <= HOOKS_BUDGET, found


if __name__ == "__main__":
    for name, number in counts().items():
        print(f"{number:5d}  {name}")
