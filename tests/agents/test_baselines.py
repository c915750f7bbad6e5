"""The fair baselines: they learn the paper's task and each explores the way its docstring says."""

from __future__ import annotations

import random
from collections import Counter
from typing import Any

import gymnasium as gym
import numpy as np
import pytest
from stable_baselines3.common.callbacks import BaseCallback, StopTrainingOnMaxEpisodes

import sb3_affect  # noqa: F401  (registers the envs)
from sb3_affect.agents.baselines import (
    Boltzmann,
    DecayingEpsilonGreedy,
    OptimisticQLearning,
    SpeedEpsilonGreedy,
    UCBQLearning,
    softmax_action,
)
from sb3_affect.agents.tabular import TabularQAlgorithm

ENV_ID = "sb3_affect/GridPursuit-v0"


def train(cls: type[TabularQAlgorithm], seed: int, episodes: int = 200, callback: Any = None, **kwargs: Any) -> Any:
    model = cls("Grid", gym.make(ENV_ID), seed=seed, **kwargs)
    callbacks = [StopTrainingOnMaxEpisodes(episodes)] + ([callback] if callback is not None else [])
    model.learn(10**8, callback=callbacks)
    return model


LEARNERS = [
    (DecayingEpsilonGreedy, {}),
    (Boltzmann, {"temperature": 1.0}),
    (Boltzmann, {"temperature": 10.0, "temperature_final": 0.1, "temperature_decay_episodes": 100}),
    (UCBQLearning, {}),
    (OptimisticQLearning, {"q_init": 1.0}),
    (SpeedEpsilonGreedy, {"exploration_rate": 0.05}),
]


@pytest.mark.parametrize(("cls", "kwargs"), LEARNERS, ids=lambda v: getattr(v, "__name__", str(v)))
def test_baseline_finds_the_optimal_greedy_path(cls: type[TabularQAlgorithm], kwargs: dict[str, Any]) -> None:
    found = 0
    for seed in range(4):
        log = train(cls, seed, **kwargs).episode_log
        assert len(log) == 200
        assert log["decisions"].tail(20).mean() < log["decisions"].head(20).mean()
        found += bool(log["greedy_optimal"].iloc[-1])
    assert found >= 3, f"{cls.__name__}: the greedy path was optimal after 200 episodes in only {found} of 4 seeds"


def test_optimistic_default_explores_then_walks_the_shortest_path() -> None:
    for seed in range(3):
        model = train(OptimisticQLearning, seed)
        assert model.q_init == 100.0 and model.exploration_rate == 0.0
        log = model.episode_log
        assert (log["random_moves"] == 0).all()  # no epsilon: only optimism explores
        assert log["optimal"].any()
        assert log["cells"].tail(20).mean() <= 13.0 < log["cells"].head(20).mean()


def test_softmax_low_temperature_is_greedy_with_random_ties() -> None:
    rng = random.Random(0)
    row = [1.0, 2.0, 0.5, 2.0]
    counts = Counter(softmax_action(row, 1 / 1e-3, rng.random()) for _ in range(2000))
    assert set(counts) == {1, 3}
    assert 800 < counts[1] < 1200


def test_softmax_high_temperature_is_near_uniform() -> None:
    rng = random.Random(1)
    row = [0.0, 100.0, 50.0, 3.0]
    counts = Counter(softmax_action(row, 1 / 1e6, rng.random()) for _ in range(8000))
    assert all(abs(counts[a] / 8000 - 0.25) < 0.03 for a in range(4))


def test_softmax_matches_the_boltzmann_probabilities() -> None:
    rng = random.Random(2)
    row = [0.0, 1.0, 2.0, 0.0]
    n = 20000
    counts = Counter(softmax_action(row, 1.0, rng.random()) for _ in range(n))
    p = np.exp(row) / np.exp(row).sum()
    assert all(abs(counts[a] / n - p[a]) < 0.015 for a in range(4))


def test_boltzmann_temperature_decays_over_episodes() -> None:
    model = Boltzmann("Grid", ENV_ID, temperature=10.0, temperature_final=0.1, temperature_decay_episodes=10)
    assert model.temperature_at(0) == pytest.approx(10.0)
    assert model.temperature_at(5) == pytest.approx(1.0)
    assert model.temperature_at(10) == pytest.approx(0.1) == model.temperature_at(50)
    fixed = Boltzmann("Grid", ENV_ID, temperature=0.5)
    assert fixed.temperature_at(100) == 0.5
    with pytest.raises(ValueError):
        Boltzmann("Grid", ENV_ID, temperature=0.0)


class StepCounter(gym.Wrapper):
    def __init__(self, env: gym.Env) -> None:
        super().__init__(env)
        self.steps = 0

    def step(self, action: Any) -> Any:
        self.steps += 1
        return self.env.step(action)


class CellsPerDecision(BaseCallback):
    def __init__(self, counter: StepCounter) -> None:
        super().__init__()
        self.counter = counter
        self.last = 0
        self.moves: list[tuple[int, bool]] = []

    def _on_step(self) -> bool:
        self.moves.append((self.counter.steps - self.last, bool(self.locals["dones"][0])))
        self.last = self.counter.steps
        return True


def test_speed_baseline_moves_one_or_two_cells_per_decision() -> None:
    counter = StepCounter(gym.make(ENV_ID))
    model = SpeedEpsilonGreedy("Grid", counter, seed=3)
    callback = CellsPerDecision(counter)
    model.learn(10**8, callback=[StopTrainingOnMaxEpisodes(30), callback])
    cells = Counter(k for k, _ in callback.moves)
    assert set(cells) == {1, 2} and min(cells.values()) > 0.3 * sum(cells.values())
    # a 2-cell decision stops early only at the goal
    assert all(k == 2 or done or k == 1 for k, done in callback.moves)
    log = model.episode_log
    assert (log["cells"] > log["decisions"]).all() and (log["cells"] <= 2 * log["decisions"]).all()
    assert (log["waits"] == 0).all()
    with_waits = train(SpeedEpsilonGreedy, 0, episodes=20, speeds=(0, 1, 2))
    assert with_waits.episode_log["waits"].sum() > 0
    with pytest.raises(ValueError):
        SpeedEpsilonGreedy("Grid", ENV_ID, speeds=())


def test_decaying_epsilon_schedule() -> None:
    model = DecayingEpsilonGreedy("Grid", ENV_ID, exploration_decay_episodes=20)
    assert model.epsilon_at(0) == 1.0
    assert model.epsilon_at(10) == pytest.approx(0.525)
    assert model.epsilon_at(20) == model.epsilon_at(99) == 0.05
    exp = DecayingEpsilonGreedy("Grid", ENV_ID, exploration_final_eps=0.01, exploration_decay_episodes=2, decay="exponential")
    assert exp.epsilon_at(1) == pytest.approx(0.1)
    with pytest.raises(ValueError):
        DecayingEpsilonGreedy("Grid", ENV_ID, exploration_final_eps=0.0, decay="exponential")
    log = train(DecayingEpsilonGreedy, 0, episodes=60, exploration_decay_episodes=20, exploration_final_eps=0.0).episode_log
    assert log["random_moves"].iloc[0] == log["decisions"].iloc[0]  # epsilon 1: every move random
    assert (log["random_moves"].iloc[25:] == 0).all()  # epsilon 0 after the decay


def test_ucb_counts_every_decision_and_tries_each_action_first() -> None:
    model = train(UCBQLearning, 0, episodes=5)
    counts = np.array(model.counts)
    assert counts.sum() == model.num_timesteps
    tried = counts[counts.sum(axis=1) > 0]
    # an action is repeated in a cell only once every action there has been tried
    assert ((tried.max(axis=1) <= 1) | (tried.min(axis=1) >= 1)).all()


def test_baselines_save_and_load(tmp_path: Any) -> None:
    for cls, kwargs in [(UCBQLearning, {}), (Boltzmann, {"temperature": 2.0}), (SpeedEpsilonGreedy, {"speeds": (1, 2)})]:
        model = train(cls, 1, episodes=10, **kwargs)
        model.save(tmp_path / cls.__name__)
        loaded = cls.load(tmp_path / cls.__name__, env=gym.make(ENV_ID))
        np.testing.assert_array_equal(loaded.q_table, model.q_table)
        if cls is UCBQLearning:
            assert loaded.counts == model.counts
        loaded.learn(10**8, callback=StopTrainingOnMaxEpisodes(3))
        assert len(loaded.episode_log) == 3


def test_baseline_sweep_runs_and_summary_ranks(tmp_path: Any) -> None:
    """The comparison's sweep file, cut to two agents, two tasks and two seeds, through the launcher; then the ranking."""
    from pathlib import Path

    import yaml

    from sb3_affect.study.launcher import run_sweep
    from sb3_affect.study.report.reading.baseline_ranks import (
        bootstrap_ci,
        load_run_records,
        markdown,
        record_metrics,
        summarise,
    )

    experiments = Path(__file__).resolve().parents[2] / "experiments"
    for name in ("baselines", "baselines_moving7"):
        spec = yaml.safe_load((experiments / f"{name}.yaml").read_text())
        spec["agents"] = [a for a in spec["agents"] if a["name"] in ("affective", "ucb")]
        spec["seeds"], spec["episodes"] = [0, 1], 15
        path = tmp_path / f"{name}.yaml"
        path.write_text(yaml.safe_dump(spec))
        summary = run_sweep(path, tmp_path / name, workers=1, progress=False)
        assert (summary.total, summary.failed) == (4, 0)
    records = load_run_records(tmp_path / "baselines") + load_run_records(tmp_path / "baselines_moving7")
    assert len(records) == 8
    moving = next(r for r in records if r["config"]["env_kwargs"].get("size") == 7)
    metrics = record_metrics(moving)
    cells, truncated = moving["episodes"]["cells"], moving["episodes"]["truncated"]
    flags = [not t and c <= 6 for c, t in zip(cells, truncated)]  # capture distance (0, 0) -> (3, 3)
    first = flags.index(True) if True in flags else len(cells)
    assert metrics["steps_before_optimal"] == sum(moving["episodes"]["decisions"][:first])
    summary = summarise(records)
    assert len(summary) == 4 and (summary["runs"] == 2).all()
    assert (summary["decisions_per_episode_low"] <= summary["decisions_per_episode"]).all()
    assert "ranks" in markdown(summary)
    mean, low, high = bootstrap_ci([1.0, 2.0, 3.0, 4.0])
    assert mean == 2.5 and 1.0 <= low < mean < high <= 4.0
    assert bootstrap_ci([5.0, 5.0]) == (5.0, 5.0, 5.0)


@pytest.mark.parametrize("name", ["baselines", "baselines_moving", "baselines_moving7", "baselines_tuning"])
def test_experiment_files_validate(name: str) -> None:
    from pathlib import Path

    from sb3_affect.core.registry import resolve_class
    from sb3_affect.study.launcher.sweep_file import load_sweep

    sweep = load_sweep(Path(__file__).resolve().parents[2] / "experiments" / f"{name}.yaml")
    for agent in sweep.agents:
        resolve_class(agent.algo)
    if name != "baselines_tuning":
        names = {a.name for a in sweep.agents}
        assert {"affective", "epsilon-greedy-paper", "epsilon-greedy-best", "epsilon-decay", "boltzmann", "ucb"} <= names
        assert {"optimistic-q100", "speed-epsilon-greedy", "affective-optimistic", "affective-pessimistic"} <= names
        assert sweep.seeds == list(range(20)) and sweep.episodes == 200
