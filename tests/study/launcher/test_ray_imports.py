"""
The Ray backend imports Ray in one place (``launcher.run_ray``, after setting the environment Ray reads when it is first
imported): no other module of the study imports Ray or the backend's modules, and without the ``ray`` extra the backend
says which extra to install.
"""

from __future__ import annotations

import json
import pkgutil
import subprocess
import sys

import pytest

import sb3_affect.study as study
from sb3_affect.core.extras import MissingExtraError
from sb3_affect.study.launcher.launcher import run_ray

#: The modules of the Ray backend, which import Ray at their top (``run_ray`` imports them).
RAY_BACKEND = ("ray_cluster", "ray_connect")


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
    with pytest.raises(MissingExtraError, match=r"the ray backend needs the 'ray' extra \(missing: ray\): pip install"):
        run_ray([], 1, lambda job, result: None, lambda job, error: None)
