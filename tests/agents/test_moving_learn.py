"""
``learn`` on MovingPursuit runs on the moving-prey kernel: the same results as the Python loop, continued on either
engine in any order, and the same callback locals at episode ends (also on the grid kernel).
"""

from __future__ import annotations

from typing import Any

import gymnasium as gym
import numpy as np
import pandas as pd
import pytest
from stable_baselines3.common.callbacks import BaseCallback, StopTrainingOnMaxEpisodes

from sb3_affect import AffectQ, QLearning
from sb3_affect.agents.baselines import Boltzmann, UCBQLearning
from sb3_affect.engine.simulation import simulate

MOVING = "sb3_affect/MovingPursuit-v0"
SMALL = {"size": 5, "prey_start": (3, 3), "max_episode_steps": 80}
AGENTS = [(AffectQ, {}), (QLearning, {"exploration_rate": 0.2}), (UCBQLearning, {}), (Boltzmann, {})]


def _everything(model: Any) -> dict[str, Any]:
    monitor = model.env.envs[0]
    base = monitor.unwrapped
    state = {
        "log": model.episode_log.fillna(-1.0).to_dict("list"),  # NaN != NaN
        "q": model.q_table.tolist(),
        "rng": model._rng.getstate(),
        "prey_rng": base.np_random.bit_generator.state,
        "cells": (base.hunter, base.prey_cell),
        "t": model.num_timesteps,
        "episode_state": model._episode_state,
        "last_obs": model._last_obs.tolist(),
        "episodes": model._episode_num,
        "ep_info": [(e["r"], e["l"], e["c"]) for e in model.ep_info_buffer],
        "monitor": (monitor.rewards, monitor.episode_returns, monitor.episode_lengths, monitor.total_steps),
        "time_limit": monitor.env._elapsed_steps,
    }
    if isinstance(model, AffectQ):
        state["appraisal"] = model.emotion_callback.appraiser.get_state()
        state["counts"] = model.emotion_callback.counts
    if isinstance(model, UCBQLearning):
        state["ucb"] = (model.counts, model._totals)
    return state


@pytest.mark.parametrize("cls, kwargs", AGENTS, ids=[cls.__name__ for cls, _ in AGENTS])
@pytest.mark.parametrize("prey", ["random", "evade", "static"])
def test_learning_on_moving_prey_continues_on_either_engine(cls: type, kwargs: dict[str, Any], prey: str) -> None:
    results = []
    for first, second in (("python", "python"), ("python", "compiled"), ("compiled", "python"), ("compiled", "compiled")):
        model = cls("Grid", gym.make(MOVING, prey=prey, **SMALL), seed=1, engine=first, **kwargs)
        model.learn(1537)  # stops in the middle of an episode
        model.engine = second
        model.learn(3000, reset_num_timesteps=False, callback=StopTrainingOnMaxEpisodes(9))
        model.engine = first
        model.learn(411, reset_num_timesteps=False)
        results.append(_everything(model))
    assert results[0]["episodes"] > 20
    assert results[1] == results[0] and results[2] == results[0] and results[3] == results[0]


def test_auto_learns_on_the_moving_kernel_as_simulate_does() -> None:
    model = AffectQ("Grid", gym.make(MOVING, size=7, prey="evade", prey_speed=0.5), seed=5)
    assert model._use_kernel(model.env.envs[0], None)
    model.learn(10**6, callback=StopTrainingOnMaxEpisodes(30))
    rows = simulate("AffectQ", {}, MOVING, {"size": 7, "prey": "evade", "prey_speed": 0.5}, [5], 30)
    expected = rows.drop(columns="seed").reset_index(drop=True)
    pd.testing.assert_frame_equal(model.episode_log, expected, check_dtype=False)
    wrapped = gym.wrappers.TransformReward(gym.make(MOVING), lambda r: 2 * r)
    with pytest.raises(ValueError, match="wrapped in TransformReward"):
        AffectQ("Grid", wrapped, engine="compiled").learn(10)


class EpisodeEndLocals(BaseCallback):
    """What the callbacks see at each episode end (on the Python loop it is called every decision)."""

    episode_level = True

    def __init__(self) -> None:
        super().__init__()
        self.seen: list[tuple[Any, ...]] = []

    def _on_step(self) -> bool:
        if self.locals["dones"][0]:
            info = {k: v for k, v in self.locals["infos"][0].items() if k != "episode"}
            episode = self.locals["infos"][0].get("episode")
            self.seen.append(
                (
                    self.num_timesteps,
                    self.locals["new_obs"].tolist(),
                    self.locals["new_obs"].dtype,
                    self.locals["rewards"].tolist(),
                    self.locals["rewards"].dtype,
                    self.locals["actions"].tolist(),
                    info,
                    None if episode is None else (episode["r"], episode["l"]),
                )
            )
        return True


@pytest.mark.parametrize(
    "env_id, env_kwargs",
    [
        (MOVING, {"size": 5, "prey_start": (3, 3), "step_reward": -1.0, "max_episode_steps": 40}),
        ("sb3_affect/GridPursuit-v0", {"size": 6, "goal": (3, 4), "step_reward": -1.0, "max_episode_steps": 30}),
    ],
)
def test_episode_end_callback_locals_are_the_python_loops(env_id: str, env_kwargs: dict[str, Any]) -> None:
    seen = {}
    for engine in ("python", "compiled"):
        ends = EpisodeEndLocals()
        model = AffectQ("Grid", gym.make(env_id, **env_kwargs), seed=2, engine=engine)
        model.learn(10**6, callback=[ends, StopTrainingOnMaxEpisodes(25)])
        seen[engine] = ends.seen
    assert len(seen["python"]) == 25
    assert any(info.get("TimeLimit.truncated") for *_, info, _ in seen["python"])  # both kinds of episode end
    assert any(not info.get("TimeLimit.truncated") for *_, info, _ in seen["python"])
    assert any(rewards[0] not in (-1.0, 100.0) for _, _, _, rewards, *_ in seen["python"])  # a 2-cell decision's sum
    assert seen["compiled"] == seen["python"]
    assert np.dtype(seen["python"][0][4]) == np.float32  # SB3's VecEnv rewards


class TablesAtEpisodeEnds(BaseCallback):
    """The Q-table and a greedy action as a callback sees them at each episode end (the table being learnt)."""

    episode_level = True

    def __init__(self) -> None:
        super().__init__()
        self.tables: list[Any] = []

    def _on_step(self) -> bool:
        if self.locals["dones"][0]:
            action, _ = self.model.predict(self.locals["new_obs"], deterministic=True)
            self.tables.append((self.model.q_table.tolist(), action.tolist()))
        return True


@pytest.mark.parametrize("env_id, env_kwargs", [(MOVING, SMALL), ("sb3_affect/GridPursuit-v0", {"size": 6, "goal": (3, 4)})])
def test_a_callback_sees_the_table_being_learnt_on_either_engine(env_id: str, env_kwargs: dict[str, Any]) -> None:
    tables = {}
    for engine in ("python", "compiled"):
        seen = TablesAtEpisodeEnds()
        model = QLearning("Grid", gym.make(env_id, **env_kwargs), seed=4, engine=engine, exploration_rate=0.3)
        model.learn(10**6, callback=[seen, StopTrainingOnMaxEpisodes(12)])
        tables[engine] = seen.tables
    assert len(tables["python"]) == 12 and tables["python"][0][0] != tables["python"][-1][0]  # it learns
    assert tables["compiled"] == tables["python"]
