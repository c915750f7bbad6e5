"""
Imports inside functions in ``sb3_affect/study/``: each says on its line why it is not at the top of its module (the
optional extra it needs, or what it keeps off a path: torch off the tabular sweep path, pandas off the launcher's,
the extras off ``--help``), and there are fewer than ``MOST`` of them.
"""

from __future__ import annotations

import ast
from pathlib import Path

STUDY = Path(__file__).resolve().parents[2] / "sb3_affect" / "study"
#: The most imports inside functions ``study/`` may hold (the top of the module is the place of every other import).
MOST = 19


def function_imports() -> list[tuple[Path, int, str]]:
    """``(module, line, the statement's lines)`` of every import nested in a function of ``study/``."""
    found = []
    for path in sorted(STUDY.rglob("*.py")):
        source = path.read_text()
        lines = source.splitlines()
        for node in nested_imports(ast.parse(source), False):
            found.append((path, node.lineno, "\n".join(lines[node.lineno - 1 : node.end_lineno])))
    return found


def nested_imports(node: ast.AST, inside: bool) -> list[ast.Import | ast.ImportFrom]:
    """The import statements under ``node`` that a function holds (``inside``: ``node`` is in a function)."""
    found: list[ast.Import | ast.ImportFrom] = []
    for child in ast.iter_child_nodes(node):
        if inside and isinstance(child, (ast.Import, ast.ImportFrom)):
            found.append(child)
        found += nested_imports(child, inside or isinstance(child, (ast.FunctionDef, ast.AsyncFunctionDef, ast.Lambda)))
    return found


def test_each_import_inside_a_function_says_why() -> None:
    bare = [f"{path.relative_to(STUDY)}:{line}: {text.strip()}" for path, line, text in function_imports() if "#" not in text]
    assert not bare, "imports inside functions without a reason on their line:\n" + "\n".join(bare)


def test_imports_inside_functions_stay_few() -> None:
    imports = function_imports()
    assert imports, "the count reads the study's modules"
    assert len(imports) < MOST, f"{len(imports)} imports inside functions in study/ (fewer than {MOST} allowed)"
