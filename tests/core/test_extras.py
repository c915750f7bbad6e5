"""The core install and its extras: numba's fallback, one line naming a missing extra, what the plugin imports."""

from __future__ import annotations

import os
import subprocess
import sys
import warnings
from pathlib import Path

import gymnasium as gym
import pytest
from stable_baselines3.common.callbacks import StopTrainingOnMaxEpisodes

import sb3_affect.core.extras
from sb3_affect import AffectQ, QLearning
from sb3_affect.core.extras import EXTRAS, MissingExtraError, missing_modules, require_extra

GRID = "sb3_affect/GridPursuit-v0"
SMALL = {"size": 6, "goal": (3, 4)}


def _learn(cls: type, engine: str) -> object:
    model = cls("Grid", gym.make(GRID, **SMALL), seed=3, engine=engine)
    model.learn(4 * model.max_episode_decisions, callback=StopTrainingOnMaxEpisodes(4))
    return model


@pytest.mark.parametrize("cls", [QLearning, AffectQ])
def test_auto_engine_without_numba_runs_the_python_loop_with_one_warning(cls: type, monkeypatch: pytest.MonkeyPatch) -> None:
    expected = _learn(cls, "python")
    monkeypatch.setitem(sys.modules, "numba", None)  # `import numba` now raises ImportError
    monkeypatch.setattr(sb3_affect.core.extras, "_NUMBA_WARNED", False)
    with pytest.warns(RuntimeWarning, match="numba can not be imported.*Python loop") as record:
        model = _learn(cls, "auto")
        _learn(cls, "auto")
    assert len([w for w in record if issubclass(w.category, RuntimeWarning)]) == 1
    assert model.q_table.tolist() == expected.q_table.tolist()  # type: ignore[attr-defined]
    assert model.episode_log.equals(expected.episode_log)  # type: ignore[attr-defined]


def test_compiled_engine_without_numba_names_it(monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.setitem(sys.modules, "numba", None)
    model = QLearning("Grid", gym.make(GRID, **SMALL), seed=0, engine="compiled")
    with pytest.raises(ModuleNotFoundError, match=r"engine='compiled' needs numba.*pip install numba"):
        model.learn(10)


def test_auto_engine_with_numba_does_not_warn() -> None:
    with warnings.catch_warnings():
        warnings.simplefilter("error", RuntimeWarning)
        _learn(QLearning, "auto")


def test_require_extra_names_the_extra_and_the_missing_module(monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.setitem(sys.modules, "lifelines", None)
    assert missing_modules("report") == ["lifelines"]
    with pytest.raises(MissingExtraError, match=r"the report needs the 'report' extra \(missing: lifelines\): "
                                                r"pip install \"sb3-affect\[report\]\""):
        require_extra("report", "the report")
    require_extra("experiments", "the launcher")  # installed: no error
    with pytest.raises(ValueError, match=r"extra='reports' is not an extra of sb3-affect; known: .*report"):
        missing_modules("reports")


def _run_blocked(blocked: str, argv: list[str], cwd: Path) -> subprocess.CompletedProcess[str]:
    """``sb3-affect ARGV`` in a process where ``import BLOCKED`` fails, as it does when the extra is not installed."""
    code = f"import sys; sys.modules[{blocked!r}] = None; from sb3_affect.study.cli import main; sys.exit(main({argv!r}))"
    env = {**os.environ, "PYTHONWARNINGS": "ignore"}
    return subprocess.run([sys.executable, "-c", code], cwd=cwd, env=env, capture_output=True, text=True, timeout=300)


@pytest.mark.parametrize(
    ("blocked", "argv", "extra"),
    [
        ("statsmodels", ["report", "."], "report"),
        ("pyarrow", ["run", "smoke", "--out", "out"], "experiments"),
        ("yaml", ["status", "."], "experiments"),
    ],
)
def test_cli_without_an_extra_says_in_one_line_which_to_install(
    blocked: str, argv: list[str], extra: str, tmp_path: Path
) -> None:
    (tmp_path / "sweep.json").write_text("{}")
    result = _run_blocked(blocked, argv, tmp_path)
    assert result.returncode == 2, result.stderr
    lines = result.stderr.strip().splitlines()
    assert len(lines) == 1, result.stderr
    assert f'pip install "sb3-affect[{extra}]"' in lines[0] and blocked in lines[0]


def test_every_extra_module_is_known() -> None:
    """The extras' modules are real module names of the libraries the pyproject lists (all installed here)."""
    for extra in ("experiments", "report", "hunters", "zoo"):
        assert missing_modules(extra) == [], extra
    assert set(EXTRAS["experiments"]) <= set(EXTRAS["report"])


def test_the_plugin_imports_no_study_module() -> None:
    """
    Training and both callbacks import no module of the study (libraries such as pandas or numba may import an
    extra's library that happens to be installed; the wheel test checks a venv that has none of them).
    """
    code = """
import sys, gymnasium as gym
from stable_baselines3 import DQN
from sb3_affect import AffectQ, BroekensCallback, EmotionCallback, QLearning
AffectQ("Grid", gym.make("sb3_affect/GridPursuit-v0", size=5, goal=(2, 3)), seed=0).learn(300)
DQN("MlpPolicy", "FrozenLake-v1", learning_starts=10, seed=0).learn(64, callback=[EmotionCallback(), BroekensCallback()])
study = ("sb3_affect.study", "sb3_affect.envs.hunter_pursuit",
         "sb3_affect.engine.simulation", "sb3_affect.agents.hunter_team")
print("LOADED", sorted(m for m in sys.modules if m.startswith(study)))
"""
    result = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=300)
    assert result.returncode == 0, result.stderr
    assert "LOADED []" in result.stdout, result.stdout
