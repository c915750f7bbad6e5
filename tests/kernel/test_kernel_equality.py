"""
The compiled engine's contract: for the same seed it gives the identical episode log, Q-table, random
generator state and appraisal as the Python loop, for every agent, reading and env it runs, over 100 seeds each.
"""

from __future__ import annotations

from typing import Any

import gymnasium as gym
import numpy as np
import pandas as pd
import pytest
from stable_baselines3.common.callbacks import StopTrainingOnMaxEpisodes
from stable_baselines3.common.utils import LinearSchedule

from sb3_affect import AffectQ, Behaviour, Emotion, QLearning
from sb3_affect.agents.baselines import Boltzmann, DecayingEpsilonGreedy, OptimisticQLearning, SpeedEpsilonGreedy, UCBQLearning
from sb3_affect.engine.simulation import simulate

GRID = "sb3_affect/GridPursuit-v0"
MAZE = "sb3_affect/MazePursuit-v0"
SMALL = {"size": 6, "goal": (3, 4)}
SEEDS = list(range(100))
TABLE = {
    Emotion.JOY: Behaviour(False, (0, 1, 2)),
    Emotion.SADNESS: Behaviour(True, (1,)),
    Emotion.FEAR: Behaviour(True, (2, 0)),
    Emotion.ANGER: Behaviour(True, (1, 2, 3)),
}
READINGS = [
    {"comparison": c, "act": a, "units": u}
    for c in ("literal", "valence")
    for a in ("episode", "remaining")
    for u in ("cells", "decisions")
]

# (id, agent class, agent kwargs, env id, env kwargs, episodes)
CASES: list[tuple[str, type, dict[str, Any], str, dict[str, Any], int]] = [
    ("qlearning-paper-grid", QLearning, {}, GRID, {}, 3),
    (
        "qlearning-eps0.6-alpha0.5-qinit1",
        QLearning,
        {"exploration_rate": 0.6, "learning_rate": 0.5, "q_init": 1.0},
        GRID,
        SMALL,
        12,
    ),
    ("qlearning-progress-schedule", QLearning, {"exploration_rate": LinearSchedule(1.0, 0.1, 0.5)}, GRID, SMALL, 5),
    ("qlearning-tie-first-cap", QLearning, {"tie_break": "first", "max_episode_decisions": 40}, GRID, SMALL, 5),
    ("affectq-paper-grid", AffectQ, {}, GRID, {}, 3),
    *((f"affectq-{r['comparison']}-{r['act']}-{r['units']}", AffectQ, r, GRID, SMALL, 5) for r in READINGS),
    ("affectq-optimistic", AffectQ, {"personality": "optimistic"}, GRID, SMALL, 5),
    ("affectq-pessimistic-valence", AffectQ, {"personality": "pessimistic", "comparison": "valence"}, GRID, SMALL, 5),
    ("affectq-behaviour-table", AffectQ, {"behaviour_table": TABLE}, GRID, SMALL, 5),
    (
        "affectq-jump-tie-first",
        AffectQ,
        {"multi_cell": "jump", "tie_break": "first", "max_episode_decisions": 60},
        GRID,
        SMALL,
        12,
    ),
    ("affectq-time-limit", AffectQ, {}, GRID, {**SMALL, "max_episode_steps": 20}, 5),
    ("affectq-obstacles", AffectQ, {}, GRID, {**SMALL, "obstacles": [(1, 1), (2, 1), (3, 3), (0, 4)]}, 5),
    ("affectq-maze-rooms", AffectQ, {"max_episode_decisions": 200}, MAZE, {"maze": "rooms"}, 3),
    ("qlearning-maze-zigzag", QLearning, {"max_episode_decisions": 200}, MAZE, {"maze": "zigzag"}, 3),
    ("decaying-linear", DecayingEpsilonGreedy, {"exploration_decay_episodes": 4}, GRID, SMALL, 5),
    (
        "decaying-exponential",
        DecayingEpsilonGreedy,
        {"exploration_decay_episodes": 3, "decay": "exponential"},
        GRID,
        SMALL,
        12,
    ),
    ("boltzmann", Boltzmann, {"temperature": 2.0}, GRID, SMALL, 5),
    (
        "boltzmann-decay",
        Boltzmann,
        {"temperature": 5.0, "temperature_final": 0.5, "temperature_decay_episodes": 3},
        GRID,
        SMALL,
        12,
    ),
    ("ucb", UCBQLearning, {"exploration_coef": 3.0}, GRID, SMALL, 5),
    ("optimistic", OptimisticQLearning, {}, GRID, SMALL, 5),
    ("speed", SpeedEpsilonGreedy, {"speeds": (0, 1, 2)}, GRID, SMALL, 5),
    ("speed-jump", SpeedEpsilonGreedy, {"speeds": (1, 2), "multi_cell": "jump"}, GRID, SMALL, 5),
]


def trained(
    cls: type, kwargs: dict[str, Any], env_id: str, env_kwargs: dict[str, Any], seed: int, episodes: int, engine: str
) -> Any:
    model = cls("Grid", gym.make(env_id, **env_kwargs), seed=seed, engine=engine, **kwargs)
    model.learn(episodes * model.max_episode_decisions, callback=StopTrainingOnMaxEpisodes(episodes))  # as simulate does
    return model


def run_state(model: Any) -> dict[str, Any]:
    """Everything a run leaves behind that the next decision depends on."""
    state: dict[str, Any] = {
        "q": model.q_table.tolist(),
        "rng": model._rng.getstate(),
        "num_timesteps": model.num_timesteps,
        "episode_state": model._episode_state,
        "episode_num": model._episode_num,
        "truncated": model.truncated_episodes,
        "env_state": model.env.envs[0].unwrapped.state,
        "ep_info": [(e["r"], e["l"], e["c"]) for e in model.ep_info_buffer],
    }
    if isinstance(model, AffectQ):
        state["appraisal"] = model.emotion_callback.appraiser.get_state()
        state["counts"] = list(model.emotion_callback.counts)
    if isinstance(model, UCBQLearning):
        state["ucb"] = (model.counts, model._totals)
    return state


@pytest.mark.slow
@pytest.mark.parametrize("case", CASES, ids=[c[0] for c in CASES])
def test_compiled_equals_python_for_100_seeds(case: tuple[str, type, dict[str, Any], str, dict[str, Any], int]) -> None:
    _, cls, kwargs, env_id, env_kwargs, episodes = case
    frames = []
    for seed in SEEDS:
        python = trained(cls, kwargs, env_id, env_kwargs, seed, episodes, "python")
        compiled = trained(cls, kwargs, env_id, env_kwargs, seed, episodes, "compiled")
        pd.testing.assert_frame_equal(compiled.episode_log, python.episode_log)
        assert run_state(compiled) == run_state(python), f"seed {seed}"
        frame = python.episode_log
        frame.insert(0, "seed", seed)
        frames.append(frame)
    expected = pd.concat(frames, ignore_index=True)
    if cls is QLearning and callable(kwargs.get("exploration_rate")):
        with pytest.raises(ValueError, match="depends on the training progress"):
            simulate(cls, kwargs, env_id, env_kwargs, SEEDS, episodes, engine="compiled")
        batch = simulate(cls, kwargs, env_id, env_kwargs, SEEDS[:5], episodes)  # auto: one learn per seed
        pd.testing.assert_frame_equal(batch, expected[expected.seed < 5].reset_index(drop=True))
    else:
        batch = simulate(cls, kwargs, env_id, env_kwargs, SEEDS, episodes, engine="compiled")
        pd.testing.assert_frame_equal(batch, expected)
    assert np.isfinite(expected["reward"]).all()
