"""How the study's modules import each other: no module imports a name another module keeps private (``_name``)."""

from __future__ import annotations

import ast
from pathlib import Path

import sb3_affect.study as study

STUDY = Path(study.__file__).parent


def private_imports(root: Path) -> list[str]:
    """``module: imported`` for each private name (one leading underscore) a module under ``root`` imports from the package."""
    found = []
    for path in sorted(root.rglob("*.py")):
        for node in ast.walk(ast.parse(path.read_text(), filename=str(path))):
            if isinstance(node, ast.ImportFrom) and (node.module or "").startswith("sb3_affect"):
                names = [alias.name for alias in node.names if alias.name.startswith("_") and not alias.name.startswith("__")]
                found += [f"{path.relative_to(root)}: {node.module}.{name}" for name in names]
    return found


def test_no_module_of_the_study_imports_a_private_name() -> None:
    assert private_imports(STUDY) == []


def test_a_private_import_is_found(tmp_path: Path) -> None:
    (tmp_path / "reader.py").write_text("def f():\n    from sb3_affect.study.launcher.store import _hidden\n")
    assert private_imports(tmp_path) == ["reader.py: sb3_affect.study.launcher.store._hidden"]
