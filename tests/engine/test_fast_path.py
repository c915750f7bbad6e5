"""
The sweep path without torch: ``import sb3_affect`` and a sweep of the package's tabular agents import
neither torch nor SB3; the kernel's inputs computed from an agent's settings (no model) equal those of a built model,
for every agent the kernel runs, on both grid envs; bad kwargs give the constructor's own error on both paths; and
each agent's settings hold exactly its constructor's defaults.
"""

from __future__ import annotations

import dataclasses
import importlib
import inspect
import json
import subprocess
import sys
import textwrap
from pathlib import Path
from typing import Any

import gymnasium as gym
import numpy as np
import pytest

import sb3_affect
from sb3_affect import AffectQ, Behaviour, Emotion, QLearning
from sb3_affect.agents.baselines import Boltzmann, DecayingEpsilonGreedy, OptimisticQLearning, SpeedEpsilonGreedy, UCBQLearning
from sb3_affect.agents.compiled import batch_reason
from sb3_affect.core.registry import known_settings
from sb3_affect.core.settings import AGENT_SETTINGS, AffectQSettings
from sb3_affect.engine.simulation import simulate
from sb3_affect.kernel.grid_inputs import BatchInputs, batch_inputs, settings_inputs
from sb3_affect.kernel.moving_batch import moving_settings_inputs
from sb3_affect.study.launcher.one_run import check_configs, settings_checkable

GRID, MAZE = "sb3_affect/GridPursuit-v0", "sb3_affect/MazePursuit-v0"
ENVS = [(GRID, {"size": 7, "goal": [3, 3]}), (MAZE, {"maze": "wall"})]
#: constructor arguments that belong to SB3 (or are objects), not settings
SB3_ARGUMENTS = {
    "policy", "env", "stats_window_size", "tensorboard_log", "policy_kwargs", "verbose", "seed", "device",
    "emotion_callback", "_init_setup_model",
}  # fmt: skip
SLOW_SAD: dict[Emotion, Behaviour] = {
    Emotion.JOY: Behaviour(True, (1,)),
    Emotion.SADNESS: Behaviour(False, (0, 1, 2)),
    Emotion.FEAR: Behaviour(True, (0,)),
    Emotion.ANGER: Behaviour(False, (2,)),
}
AGENTS: list[tuple[str, dict[str, Any]]] = [
    ("QLearning", {}),
    ("QLearning", {"exploration_rate": 0.4, "learning_rate": 0.5, "gamma": 0.9, "q_init": 1.0, "tie_break": "first"}),
    ("AffectQ", {}),
    ("AffectQ", {"comparison": "valence", "act": "remaining", "units": "decisions"}),
    ("AffectQ", {"personality": "optimistic", "multi_cell": "jump"}),
    ("AffectQ", {"personality": "pessimistic", "behaviour_table": SLOW_SAD, "max_episode_decisions": 40}),
    ("sb3_affect.agents.baselines:DecayingEpsilonGreedy", {"exploration_decay_episodes": 7, "decay": "exponential"}),
    ("sb3_affect.agents.baselines:Boltzmann", {"temperature": 2.0}),
    ("sb3_affect.agents.baselines.boltzmann:Boltzmann", {"temperature": 5.0, "temperature_final": 0.5, "temperature_decay_episodes": 9}),  # noqa: E501
    ("sb3_affect.agents.baselines:UCBQLearning", {"exploration_coef": 3.0}),
    ("sb3_affect.agents.baselines:OptimisticQLearning", {}),
    ("sb3_affect.agents.baselines:SpeedEpsilonGreedy", {"speeds": [0, 1, 2], "multi_cell": "jump", "exploration_rate": 0.2}),
]
CLASSES = {
    "QLearning": QLearning,
    "AffectQ": AffectQ,
    "DecayingEpsilonGreedy": DecayingEpsilonGreedy,
    "Boltzmann": Boltzmann,
    "UCBQLearning": UCBQLearning,
    "OptimisticQLearning": OptimisticQLearning,
    "SpeedEpsilonGreedy": SpeedEpsilonGreedy,
}


def model_inputs(algo: str, kwargs: dict[str, Any], env_id: str, env_kwargs: dict[str, Any], episodes: int) -> BatchInputs:
    """What ``simulate`` fed the kernel before: a model built as a template."""
    cls = CLASSES[algo.rpartition(":")[2] or algo]
    model = cls("Grid", gym.make(env_id, **env_kwargs), seed=0, **kwargs)
    assert batch_reason(model, episodes) is None
    return batch_inputs(model.compiled_settings(), model.single_env(), episodes)


def same_inputs(a: BatchInputs, b: BatchInputs) -> None:
    for name in ("random", "speeds", "n"):
        np.testing.assert_array_equal(getattr(a.agent.behaviour, name), getattr(b.agent.behaviour, name), err_msg=name)
    assert a.agent._replace(behaviour=None) == b.agent._replace(behaviour=None)
    assert a.config == b.config
    for name in ("alpha", "p"):
        np.testing.assert_array_equal(getattr(a, name), getattr(b, name), err_msg=name)
    for name in ("trans", "tdist"):
        np.testing.assert_array_equal(getattr(a.table, name), getattr(b.table, name), err_msg=name)
    assert (a.table.start, a.table.goal, a.table.max_pred) == (b.table.start, b.table.goal, b.table.max_pred)
    assert a.n_actions == b.n_actions


@pytest.mark.parametrize(("env_id", "env_kwargs"), ENVS, ids=["grid", "maze"])
@pytest.mark.parametrize(("algo", "kwargs"), AGENTS, ids=[f"{a.rpartition(':')[2]}-{i}" for i, (a, _) in enumerate(AGENTS)])
def test_settings_give_the_models_kernel_inputs_and_rows(
    algo: str, kwargs: dict[str, Any], env_id: str, env_kwargs: dict[str, Any]
) -> None:
    episodes, seeds = 12, [0, 7, 2**40 + 3]
    light = settings_inputs(algo, kwargs, env_id, env_kwargs, episodes)
    assert light is not None
    same_inputs(light, model_inputs(algo, kwargs, env_id, env_kwargs, episodes))
    rows = simulate(algo, kwargs, env_id, env_kwargs, seeds, episodes)
    built = simulate(algo, {**kwargs, "verbose": 0}, env_id, env_kwargs, seeds, episodes)  # not a setting: the model path
    assert len(rows) == len(seeds) * episodes
    assert rows.equals(built)


BAD: list[tuple[str, dict[str, Any]]] = [
    ("QLearning", {"exploration_rate": 1.5}),
    ("QLearning", {"gamma": "high"}),
    ("QLearning", {"learning_rate": 0.0}),
    ("QLearning", {"max_episode_decisions": 0}),
    ("QLearning", {"tie_break": "last"}),
    ("QLearning", {"engine": "fast"}),
    ("AffectQ", {"comparison": "literally"}),
    ("AffectQ", {"personality": "grumpy"}),
    ("AffectQ", {"units": "metres"}),
    ("AffectQ", {"behaviour_table": {Emotion.JOY: Behaviour(True, (1,))}}),
    ("AffectQ", {"multi_cell": "hop"}),
    ("sb3_affect.agents.baselines:DecayingEpsilonGreedy", {"decay": "exponential", "exploration_final_eps": 0.0}),
    ("sb3_affect.agents.baselines:DecayingEpsilonGreedy", {"exploration_decay_episodes": 2.5}),
    ("sb3_affect.agents.baselines:Boltzmann", {"temperature": 0.0}),
    ("sb3_affect.agents.baselines:Boltzmann", {"temperature_final": -1.0}),
    ("sb3_affect.agents.baselines:UCBQLearning", {"exploration_coef": -1}),
    ("sb3_affect.agents.baselines:SpeedEpsilonGreedy", {"speeds": []}),
    ("sb3_affect.agents.baselines:SpeedEpsilonGreedy", {"speeds": "12"}),
]


def constructor_error(algo: str, kwargs: dict[str, Any]) -> BaseException:
    cls = CLASSES[algo.rpartition(":")[2] or algo]
    with pytest.raises((TypeError, ValueError)) as caught:
        cls("Grid", GRID, seed=0, **kwargs)
    return caught.value


@pytest.mark.parametrize(("algo", "kwargs"), BAD, ids=[f"{a.rpartition(':')[2]}-{next(iter(k))}" for a, k in BAD])
def test_bad_kwargs_give_the_constructors_error_on_every_path(algo: str, kwargs: dict[str, Any]) -> None:
    expected = constructor_error(algo, kwargs)
    settings = known_settings(algo)
    assert settings is not None
    with pytest.raises(type(expected)) as direct:
        settings(**kwargs)
    assert str(direct.value) == str(expected)
    with pytest.raises(type(expected)) as through_simulate:
        simulate(algo, kwargs, GRID, {}, [1], 3)
    assert str(through_simulate.value) == str(expected)
    config = {"agent": "a", "algo": algo, "algo_kwargs": kwargs, "env_id": GRID, "env_kwargs": {}, "labels": {}, "seed": 1}
    assert settings_checkable(config)
    assert check_configs([config]) == [("a", f"{algo} can not be built: {type(expected).__name__}: {expected}")]


def test_what_the_settings_path_leaves_to_the_model() -> None:
    assert settings_inputs("AffectQ", {"device": "cpu"}, GRID, {}, 5) is None  # SB3's argument: build the model
    assert settings_inputs("QLearning", {"exploration_rate": lambda p: 0.1 * p}, GRID, {}, 5) is None  # progress schedule
    assert settings_inputs("QLearning", {}, "sb3_affect/MovingPursuit-v0", {}, 5) is None  # the moving-prey kernel's
    assert moving_settings_inputs("QLearning", {}, "sb3_affect/MovingPursuit-v0", {}, 5) is not None
    assert moving_settings_inputs("QLearning", {}, GRID, {}, 5) is None
    assert settings_inputs("DQN", {}, GRID, {}, 5) is None
    subclass = type("MyQ", (QLearning,), {})
    assert settings_inputs(subclass, {}, GRID, {}, 5) is None  # a subclass may change the loop
    assert settings_inputs(QLearning, {}, GRID, {}, 5) is not None
    # and simulate still runs them, through a model
    moving = simulate("QLearning", {}, "sb3_affect/MovingPursuit-v0", {}, [3], 2)
    assert list(moving["episode"]) == [1, 2]


def test_algo_names_of_the_packages_agents_are_known_without_importing() -> None:
    for settings in AGENT_SETTINGS:
        module, _, name = settings.agent.partition(":")
        cls = getattr(importlib.import_module(module), name)
        assert cls.settings_class is settings, name
        for package in settings.exported_from:
            assert getattr(importlib.import_module(package), name) is cls
            assert known_settings(f"{package}:{name}") is settings
            assert known_settings(f"{package}.{name}") is settings
        assert known_settings(settings.agent) is settings
    assert known_settings("QLearning") is known_settings("sb3_affect:QLearning")
    assert known_settings("AffectQ") is AffectQSettings
    others = ("DQN", "PPO", "my_package.agents:QLearning", "sb3_affect:TabularQAlgorithm", "sb3_affect.study.cli:main",
              "nonsense")
    for other in others:
        assert known_settings(other) is None, other


@pytest.mark.parametrize("settings", AGENT_SETTINGS, ids=lambda s: s.agent.partition(":")[2])
def test_each_agents_defaults_are_its_settings(settings: Any) -> None:
    """One source of truth: every constructor argument is a setting (with the setting's default) or SB3's."""
    module, _, name = settings.agent.partition(":")
    parameters = inspect.signature(getattr(importlib.import_module(module), name).__init__).parameters
    fields = {f.name: f.default for f in dataclasses.fields(settings) if f.init}
    assert set(fields) <= set(parameters)
    assert set(parameters) - {"self"} - set(fields) <= SB3_ARGUMENTS
    for field, default in fields.items():
        assert parameters[field].default == default, field


def test_import_and_a_sweep_of_tabular_agents_never_import_torch(tmp_path: Path) -> None:
    """Checked in the launcher (its forked workers inherit its modules), and in a batch run as a worker runs it: neither
    imports pandas either (the chunks are written from NumPy arrays)."""
    sweep = tmp_path / "mini.yaml"
    sweep.write_text(
        textwrap.dedent(
            """
            name: mini
            env: {id: sb3_affect/GridPursuit-v0, kwargs: {size: 7, goal: [3, 3]}}
            episodes: 15
            seeds: 3
            agents:
              - {name: eps, algo: QLearning, grid: {epsilon: [0.1, 0.5]}, kwargs: {exploration_rate: $epsilon}}
              - {name: aff, algo: AffectQ, grid: {epsilon: [0.1, 0.5]}, kwargs: {comparison: literal}}
              - {name: ucb, algo: "sb3_affect.agents.baselines:UCBQLearning", kwargs: {exploration_coef: 2.0}}
            """
        )
    )
    script = f"""
import json, sys
import sb3_affect
from sb3_affect.study.cli import build_parser
build_parser()
loaded = {{"import": sorted(m for m in ("torch", "stable_baselines3") if m in sys.modules)}}
heavy = ("sb3_affect.study.forensics.analysis", "sb3_affect.study.report", "scipy")
loaded["parser"] = sorted(m for m in heavy if m in sys.modules)
from sb3_affect.study.launcher import run_sweep
summary = run_sweep({str(sweep)!r}, {str(tmp_path / "out")!r}, workers=2, progress=False)
loaded["sweep"] = sorted(m for m in ("torch", "stable_baselines3", "pandas") if m in sys.modules)
from sb3_affect.study.launcher.launcher import plan_jobs
from sb3_affect.study.launcher.sweep_file import load_sweep
from sb3_affect.study.launcher.store import ResultsStore, cell_run_ids
cells = load_sweep({str(sweep)!r}).cells()
batch = plan_jobs(cells, [cell_run_ids(c) for c in cells], ResultsStore({str(tmp_path / "empty")!r}), 2, [])[0]
assert type(batch).__name__ == "Batch" and batch.execute()["chunk"][:4] == b"PAR1"  # what a worker does, here
loaded["batch"] = sorted(m for m in ("torch", "stable_baselines3", "pandas") if m in sys.modules)
print(json.dumps({{**loaded, "finished": summary.finished, "failed": summary.failed}}))
"""
    done = subprocess.run([sys.executable, "-c", script], capture_output=True, text=True, timeout=300, check=True)
    result = json.loads(done.stdout.strip().splitlines()[-1])
    assert result == {"import": [], "parser": [], "sweep": [], "batch": [], "finished": 15, "failed": 0}, done.stderr
    assert sb3_affect.QLearning is QLearning  # the lazy names are the classes
