"""
How the plugin's modules reach each other: reaches into another object's private attributes stay under a ceiling,
private names are not imported across modules, no import cycle exists even counting annotation-only imports, and the
engine imports nothing above it (the package root included).

A *reach* is ``x._name`` (one leading underscore) where ``x`` is not ``self``, ``cls`` or ``super()``: code that
depends on another object's private state; ``getattr(x, "_name")`` (and ``setattr``, ``hasattr``, ``delattr``) is one too.
Names that are public API spelled with an underscore (a namedtuple's ``_fields``, ``_replace``, ``_asdict``, ``_make``;
``os._exit``) are not reaches. torch's ``_foreach_*`` ops are: torch's own documentation calls them private, kept for
compatibility while the public ``torch.foreach`` replaces them.
"""

from __future__ import annotations

import ast
import collections
from pathlib import Path

import grimp
import pytest

import sb3_affect

PACKAGE = Path(sb3_affect.__file__).parent
#: Public API spelled with a leading underscore (see the module docstring).
PUBLIC_UNDERSCORE = {"_fields", "_replace", "_asdict", "_make", "_exit"}
#: The ceiling of reaches in the package, its count today (lower it when a change removes some; it may not grow).
MAX_REACHES = 45
#: The ceiling of private names imported from another module of the package: none.
MAX_PRIVATE_IMPORTS = 0


def _is_own(value: ast.expr) -> bool:
    if isinstance(value, ast.Name):
        return value.id in ("self", "cls")
    return isinstance(value, ast.Call) and isinstance(value.func, ast.Name) and value.func.id == "super" and not value.args


#: The built-ins that name an attribute by a string.
BY_NAME = {"getattr", "setattr", "hasattr", "delattr"}


def _reached(node: ast.AST) -> str | None:
    """The private name ``node`` reaches for (``x._name``, ``getattr(x, "_name")``), or None."""
    if isinstance(node, ast.Attribute):
        owner, name = node.value, node.attr
    elif (isinstance(node, ast.Call) and isinstance(node.func, ast.Name) and node.func.id in BY_NAME
          and len(node.args) >= 2 and isinstance(node.args[1], ast.Constant) and isinstance(node.args[1].value, str)):
        owner, name = node.args[0], node.args[1].value
    else:
        return None
    if not name.startswith("_") or name.startswith("__") or name in PUBLIC_UNDERSCORE or _is_own(owner):
        return None
    return name


def reaches() -> collections.Counter[str]:
    """Reaches into another object's private attributes, per module of the package."""
    found: collections.Counter[str] = collections.Counter()
    for path in sorted(PACKAGE.rglob("*.py")):
        for node in ast.walk(ast.parse(path.read_text(encoding="utf-8"))):
            if _reached(node) is not None:
                found[str(path.relative_to(PACKAGE.parent))] += 1
    return found


def private_imports() -> list[str]:
    """``module: name`` for every private name a module of the package imports from another of its modules."""
    found = []
    for path in sorted(PACKAGE.rglob("*.py")):
        for node in ast.walk(ast.parse(path.read_text(encoding="utf-8"))):
            if isinstance(node, ast.ImportFrom) and (node.module or "").startswith("sb3_affect"):
                found += [
                    f"{path.relative_to(PACKAGE.parent)}: {alias.name}"
                    for alias in node.names
                    if alias.name.startswith("_") and not alias.name.startswith("__")
                ]
    return found


def test_reaches_into_private_attributes_stay_under_the_ceiling() -> None:
    found = reaches()
    assert sum(found.values()) <= MAX_REACHES, dict(found.most_common())


def test_the_reach_counter_sees_reaches_and_skips_own_attributes() -> None:
    source = ("def f(self, model):\n    self._a = model._b + super()._c() + type(model)._d + row._fields[0]\n"
              "    getattr(model, '_e', None) or hasattr(self, '_f') or getattr(model, name) or th._foreach_add(x, 1)\n")
    nodes = list(ast.walk(ast.parse(source)))
    assert sorted(node.attr for node in nodes if isinstance(node, ast.Attribute)) == [
        "_a", "_b", "_c", "_d", "_fields", "_foreach_add"]
    assert sorted(name for name in map(_reached, nodes) if name is not None) == ["_b", "_d", "_e", "_foreach_add"]


def test_the_tabular_loop_reaches_into_nothing() -> None:
    found = reaches()
    loop = ["agents/tabular.py", "agents/reference_loop.py", "agents/stepping.py", "agents/compiled.py",
            "agents/qlearning.py", "agents/affectq.py", "agents/hunter_team.py", "engine/simulation.py"]
    assert {name: found[f"sb3_affect/{name}"] for name in loop if found[f"sb3_affect/{name}"]} == {}


def test_private_names_are_not_imported_across_modules() -> None:
    found = private_imports()
    assert len(found) <= MAX_PRIVATE_IMPORTS, found


@pytest.fixture(scope="module")
def graph() -> grimp.ImportGraph:
    """The package's imports, lazy ones inside functions and annotation-only ones included."""
    return grimp.build_graph("sb3_affect", include_external_packages=False, exclude_type_checking_imports=False)


def test_no_import_cycle_counting_annotation_only_imports(graph: grimp.ImportGraph) -> None:
    imports = {module: sorted(graph.find_modules_directly_imported_by(module)) for module in graph.modules}
    done: set[str] = set()
    for start in sorted(imports):  # depth-first, iteratively: a module met again on the current path closes a cycle
        path, on_path, todo = [start], {start}, [iter(imports[start])]
        while todo:
            following = next(todo[-1], None)
            if following is None:
                finished = path.pop()
                on_path.discard(finished)
                done.add(finished)
                todo.pop()
            elif following in on_path:
                raise AssertionError(" -> ".join([*path[path.index(following) :], following]))
            elif following not in done:
                path.append(following)
                on_path.add(following)
                todo.append(iter(imports[following]))


def test_the_engine_imports_nothing_above_it(graph: grimp.ImportGraph) -> None:
    above = ("sb3_affect.study", "sb3_affect.__main__")
    for module in sorted(m for m in graph.modules if m.startswith("sb3_affect.engine")):
        for imported in graph.find_modules_directly_imported_by(module):
            assert imported != "sb3_affect" and not imported.startswith(above), (module, imported)
