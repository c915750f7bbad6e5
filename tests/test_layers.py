"""
The package's layers (docs/architecture.md): one folder each, named in one place, the `layers` contract of
``.importlinter`` that `lint-imports` (run by `make test`) checks. These tests check what the contracts can not see:
that every folder of ``sb3_affect`` is a layer the contract names (a new module lands in a layer by where it is
saved), the envs (below the core), which live in the top-level ``envs/`` folder, and what importing the core costs.
"""

from __future__ import annotations

import ast
import configparser
import json
import subprocess
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]


def contract_layers() -> list[list[str]]:
    """The layers of the package's ``layers`` contract, top first, each a list of its (independent) packages."""
    config = configparser.ConfigParser()
    config.read(ROOT / ".importlinter")
    lines = [line.strip() for line in config["importlinter:contract:layers"]["layers"].splitlines() if line.strip()]
    return [[name.strip() for name in line.replace(":", "|").split("|")] for line in lines]


def test_the_top_level_holds_only_the_layer_folders() -> None:
    top = ROOT / "sb3_affect"
    modules = sorted(path.name for path in top.glob("*.py"))
    assert modules == ["__init__.py", "__main__.py"]
    named = {name for layer in contract_layers() for name in layer}
    folders = {f"sb3_affect.{path.parent.name}" for path in top.glob("*/__init__.py")}
    assert folders <= named, f"folders outside every layer: {sorted(folders - named)}"
    assert sorted(named - folders - {"sb3_affect.__main__"}) == []


def test_the_contract_reads_as_the_architecture_page_says() -> None:
    layers = contract_layers()
    assert layers[-1] == ["sb3_affect.core"]
    assert ["sb3_affect.study"] in layers and ["sb3_affect.agents"] in layers
    assert layers.index(["sb3_affect.study"]) < layers.index(["sb3_affect.agents"]) < layers.index(["sb3_affect.kernel"])


#: The core: what an agent is made of, importable without torch, numba or pandas.
CORE = (
    *(f"sb3_affect.core.{path.stem}" for path in sorted((ROOT / "sb3_affect" / "core").glob("*.py")) if path.stem[0] != "_"),
    "sb3_affect.envs",
)


def _imported_modules(path: Path) -> set[str]:
    names: set[str] = set()
    for node in ast.walk(ast.parse(path.read_text())):
        if isinstance(node, ast.Import):
            names.update(alias.name for alias in node.names)
        elif isinstance(node, ast.ImportFrom) and node.module and not node.level:
            names.add(node.module)
    return names


@pytest.mark.parametrize("path", sorted((ROOT / "envs").glob("*.py")), ids=lambda p: p.name)
def test_envs_import_nothing_of_the_package_but_the_envs(path: Path) -> None:
    ours = {name for name in _imported_modules(path) if name.split(".")[0] == "sb3_affect"}
    assert all(name.startswith("sb3_affect.envs") for name in ours), f"{path.name} imports {sorted(ours)}"


def test_the_core_imports_no_torch_numba_pandas_or_study_module() -> None:
    code = f"""
import json, sys
for name in {list(CORE)!r}:
    __import__(name)
heavy = ("torch", "stable_baselines3", "numba", "pandas")
study = ("sb3_affect.study", "sb3_affect.kernel", "sb3_affect.agents", "sb3_affect.engine")
print(json.dumps(sorted(m for m in sys.modules if m in heavy or m.startswith(study))))
"""
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True, cwd=ROOT)
    assert json.loads(out.stdout) == []


def _cycles(graph: dict[str, set[str]]) -> list[list[str]]:
    """The strongly connected sets of more than one module (Tarjan's algorithm, iterative)."""
    index: dict[str, int] = {}
    low: dict[str, int] = {}
    on_stack: set[str] = set()
    stack: list[str] = []
    found: list[list[str]] = []
    for root in sorted(graph):
        if root in index:
            continue
        work = [(root, iter(sorted(graph[root])))]
        index[root] = low[root] = len(index)
        stack.append(root)
        on_stack.add(root)
        while work:
            node, children = work[-1]
            child = next(children, None)
            if child is not None:
                if child not in index:
                    index[child] = low[child] = len(index)
                    stack.append(child)
                    on_stack.add(child)
                    work.append((child, iter(sorted(graph[child]))))
                elif child in on_stack:
                    low[node] = min(low[node], index[child])
                continue
            work.pop()
            if work:
                low[work[-1][0]] = min(low[work[-1][0]], low[node])
            if low[node] == index[node]:
                component = []
                while True:
                    member = stack.pop()
                    on_stack.discard(member)
                    component.append(member)
                    if member == node:
                        break
                if len(component) > 1:
                    found.append(sorted(component))
    return found


def test_no_import_cycle_between_modules() -> None:
    """Lazy imports included: no set of modules imports itself round (finer than lint-imports' sibling packages)."""
    grimp = pytest.importorskip("grimp")
    built = grimp.build_graph("sb3_affect", exclude_type_checking_imports=True)
    graph = {m: {i for i in built.find_modules_directly_imported_by(m) if i.startswith("sb3_affect")} for m in built.modules}
    graph = {m: {i for i in imported if i in graph} for m, imported in graph.items()}
    assert _cycles(graph) == []
    assert _cycles({"a": {"b"}, "b": {"c"}, "c": {"a"}, "d": {"a"}}) == [["a", "b", "c"]]  # the check itself finds one
