"""No module over 800 lines and no function over 120 (issue 16): a braided function or a
module that does several things fails here, with its name and size."""

from __future__ import annotations

import ast
from pathlib import Path

PACKAGE = Path(__file__).resolve().parents[2] / "cwproc"

MAX_MODULE_LINES = 800
MAX_FUNCTION_LINES = 120


def long_functions(path: Path, limit: int, root: Path = PACKAGE.parent) -> list[str]:
    """``file:line name (N lines)`` of every function or method of ``path`` over ``limit``."""
    out = []
    for node in ast.walk(ast.parse(path.read_text(encoding="utf-8"))):
        if isinstance(node, ast.FunctionDef | ast.AsyncFunctionDef):
            n = node.end_lineno - node.lineno + 1
            if n > limit:
                out.append(f"{path.relative_to(root)}:{node.lineno} {node.name} ({n})")
    return out


def test_no_module_over_800_lines():
    big = [
        f"{p.relative_to(PACKAGE.parent)} ({n})"
        for p in sorted(PACKAGE.rglob("*.py"))
        if (n := len(p.read_text(encoding="utf-8").splitlines())) > MAX_MODULE_LINES
    ]
    assert not big, "modules over 800 lines: " + ", ".join(big)


def test_no_function_over_120_lines():
    long = [f for p in sorted(PACKAGE.rglob("*.py")) for f in long_functions(p, MAX_FUNCTION_LINES)]
    assert not long, "functions over 120 lines:\n" + "\n".join(long)


def test_the_check_sees_a_long_function(tmp_path):
    body = "\n".join(f"    x{i} = {i}" for i in range(130))
    source = tmp_path / "braided.py"
    source.write_text(f"def braided():\n{body}\n", encoding="utf-8")
    assert long_functions(source, MAX_FUNCTION_LINES, tmp_path) == ["braided.py:1 braided (131)"]
