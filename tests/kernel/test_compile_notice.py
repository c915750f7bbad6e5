"""
``announce_compile``: the first use of a compiled feature on a machine (numba's cache cold) prints one line saying what
compiles and about how long; a cached or already compiled feature prints nothing, and nothing is printed twice.
"""

from __future__ import annotations

import importlib.util
import sys
from pathlib import Path
from typing import Any

import numba
import pytest

from sb3_affect.kernel import jit
from sb3_affect.kernel.jit import announce_compile, cached


def _fresh_kernel(folder: Path, name: str) -> Any:
    """A cached numba function in a module of its own under ``folder`` (its cache: ``folder/__pycache__``)."""
    path = folder / f"{name}.py"
    path.write_text("from numba import njit\n\n\n@njit(cache=True)\ndef add_one(x):\n    return x + 1\n")
    spec = importlib.util.spec_from_file_location(name, path)
    assert spec is not None and spec.loader is not None
    module = importlib.util.module_from_spec(spec)
    sys.modules[name] = module
    spec.loader.exec_module(module)
    return module.add_one


def test_a_cold_kernel_is_announced_once_and_a_cached_one_not(tmp_path: Path, capsys: Any,
                                                               monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.setattr(jit, "_ANNOUNCED", set())
    kernel = _fresh_kernel(tmp_path, "cold_kernel_module")
    assert not cached(kernel)
    assert announce_compile("a test kernel", [kernel], 300)
    line = capsys.readouterr().err
    assert line.count("\n") == 1
    assert "compiling a test kernel" in line and "about 5 CPU minutes" in line and "python -m sb3_affect.kernel" in line
    assert not announce_compile("a test kernel", [kernel], 300)  # once per process
    assert kernel(1) == 2  # compiles, and writes numba's cache
    assert cached(kernel)
    again = numba.njit(cache=True)(kernel.py_func)  # a new process's dispatcher: nothing compiled yet, the cache warm
    assert not again.signatures and cached(again)
    assert not announce_compile("the same kernel, cached", [again], 300)
    assert capsys.readouterr().err == ""


def test_the_minigrid_worlds_are_cached_once_used() -> None:
    from sb3_affect import minigrid_vec_env
    from sb3_affect.kernel.minigrid_world import reset_worlds, step_worlds

    minigrid_vec_env("MiniGrid-Empty-5x5-v0", 1, seed=0).reset()
    assert cached(reset_worlds) and cached(step_worlds)


@pytest.mark.parametrize("env_id", ["sb3_affect/GridPursuit-v0", "sb3_affect/MovingPursuit-v0"])
def test_simulate_announces_the_batch_kernel_it_is_about_to_compile(env_id: str, capsys: Any,
                                                                     monkeypatch: pytest.MonkeyPatch) -> None:
    from sb3_affect.engine.simulation import simulate

    monkeypatch.setattr(jit, "_ANNOUNCED", set())
    monkeypatch.setattr(jit, "cached", lambda dispatcher: False)  # as on a machine whose numba cache is cold
    simulate("AffectQ", {}, env_id, {}, [0], 2)
    line = capsys.readouterr().err
    kernel = "tabular agents' moving-prey batch kernel" if "Moving" in env_id else "tabular agents' batch kernel"
    assert line.count("\n") == 1 and f"compiling the {kernel} (simulate)" in line


def test_a_team_run_announces_the_team_loop_it_is_about_to_compile(capsys: Any, monkeypatch: pytest.MonkeyPatch) -> None:
    pytest.importorskip("pettingzoo")
    from sb3_affect.engine.team_simulation import simulate_team

    monkeypatch.setattr(jit, "_ANNOUNCED", set())
    monkeypatch.setattr(jit, "cached", lambda dispatcher: False)  # as on a machine whose numba cache is cold
    members = [("AffectQ", {}), ("QLearning", {"exploration_rate": 0.1})]
    assert simulate_team(members, "sb3_affect/HunterPursuit-v0", {}, 0, 2) is not None
    line = capsys.readouterr().err
    assert line.count("\n") == 1 and "compiling the hunter team's loop (simulate_team)" in line
