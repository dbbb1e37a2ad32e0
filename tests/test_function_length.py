"""No function of the package outside ``cli/`` is longer than 80 lines.

Every module under ``src/expertise_irl`` is parsed with :mod:`ast`; a function's length is
``end_lineno - lineno + 1`` from its ``def`` (decorators excluded), docstring included. Nested
functions and methods count on their own. The command line's modules (``cli/``) are exempt: a
command's options are most of its lines.
"""

from __future__ import annotations

import ast
from pathlib import Path

import expertise_irl

MAX_LINES = 80
ROOT = Path(expertise_irl.__file__).parent

def _functions(tree: ast.AST, prefix: str = ""):
    for node in ast.iter_child_nodes(tree):
        if isinstance(node, ast.FunctionDef | ast.AsyncFunctionDef):
            yield prefix + node.name, node
            yield from _functions(node, f"{prefix}{node.name}.")
        elif isinstance(node, ast.ClassDef):
            yield from _functions(node, f"{prefix}{node.name}.")
        else:
            yield from _functions(node, prefix)


def long_functions() -> dict[str, int]:
    """``{"path::name": lines}`` of every function over :data:`MAX_LINES` outside ``cli/``."""
    out = {}
    for path in sorted(ROOT.rglob("*.py")):
        rel = path.relative_to(ROOT)
        if rel.parts[0] == "cli":
            continue
        for name, node in _functions(ast.parse(path.read_text(encoding="utf-8"))):
            n = node.end_lineno - node.lineno + 1
            if n > MAX_LINES:
                out[f"{rel.as_posix()}::{name}"] = n
    return out


def test_no_function_outside_the_cli_is_over_80_lines():
    over = long_functions()
    assert not over, "functions over 80 lines (split them): " + ", ".join(
        f"{k} ({n} lines)" for k, n in sorted(over.items()))
