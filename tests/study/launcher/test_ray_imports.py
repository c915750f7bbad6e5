"""
The Ray backend imports Ray in one place (``launcher.executor``, after setting the environment Ray reads when it is first
imported): no other module of the study imports Ray or the backend's modules, and without the ``ray`` extra the backend
says which extra to install.
"""

from __future__ import annotations

import ast
import json
import pkgutil
import subprocess
import sys
from pathlib import Path

import pytest

import sb3_affect.study as study
from sb3_affect.core.extras import MissingExtraError
from sb3_affect.study.launcher.launcher import executor

#: The modules of the Ray backend, which import Ray at their top (``executor`` imports them).
RAY_BACKEND = ("ray_cluster", "ray_connect")
#: Who may import Ray or the backend's modules: ``module -> what it imports`` (the launcher after setting the environment).
ALLOWED = {
    "sb3_affect.study.launcher.launcher": {"sb3_affect.study.launcher.ray_cluster"},
    "sb3_affect.study.launcher.ray_cluster": {
        "ray",
        "ray.util.scheduling_strategies",
        "sb3_affect.study.launcher.ray_connect",
    },
    "sb3_affect.study.launcher.ray_connect": {"grpc", "ray.core.generated"},
}
PACKAGE = Path(study.__file__).parents[1]


def ray_imports(root: Path) -> dict[str, set[str]]:
    """``module -> the modules of Ray, gRPC or the Ray backend it imports`` (anywhere in it: top or function)."""
    found: dict[str, set[str]] = {}
    for path in sorted(root.rglob("*.py")):
        module = ".".join(path.relative_to(root.parent).with_suffix("").parts)
        for node in ast.walk(ast.parse(path.read_text())):
            names = [a.name for a in node.names] if isinstance(node, ast.Import) else []
            names += [node.module] if isinstance(node, ast.ImportFrom) and node.module and not node.level else []
            for name in names:
                if name.split(".")[0] in ("ray", "grpc") or name.rpartition(".")[2] in RAY_BACKEND:
                    found.setdefault(module, set()).add(name)
    return found


def test_only_the_launcher_imports_the_ray_backend_and_only_the_backend_imports_ray() -> None:
    assert ray_imports(PACKAGE) == ALLOWED


def test_no_module_of_the_study_but_the_ray_backends_imports_ray() -> None:
    modules = [m.name for m in pkgutil.walk_packages(study.__path__, "sb3_affect.study.")]
    others = [name for name in modules if name.rpartition(".")[2] not in RAY_BACKEND]
    assert len(others) == len(modules) - len(RAY_BACKEND)
    code = f"import importlib, json, sys\nfor name in {others!r}:\n    importlib.import_module(name)\n"
    code += "print(json.dumps(sorted(sys.modules)))"
    done = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True, timeout=300)
    loaded = json.loads(done.stdout.strip().splitlines()[-1])
    assert "sb3_affect.study.launcher.launcher" in loaded
    assert [name for name in loaded if name == "ray" or name.rpartition(".")[2] in RAY_BACKEND] == []


def test_without_the_ray_extra_the_backend_names_it(monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.setitem(sys.modules, "ray", None)  # `import ray` now raises ImportError
    refused = pytest.raises(MissingExtraError, match=r"the ray backend needs the 'ray' extra \(missing: ray\): pip install")
    with refused, executor("ray", 1):
        pass
