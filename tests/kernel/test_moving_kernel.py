"""
The moving-prey kernel's contract: on MovingPursuit, for the same seed, ``kernel.moving_loop`` gives the identical episode
log, Q-table, agent generator state (MT19937), env generator state (NumPy's PCG64, the prey's draws) and known map as
the Python loop, for every agent kind, reading and prey, over many seeds; and ``simulate`` uses it.
"""

from __future__ import annotations

from typing import Any

import gymnasium as gym
import numpy as np
import pandas as pd
import pytest
from numba import njit
from stable_baselines3.common.callbacks import StopTrainingOnMaxEpisodes

from sb3_affect import AffectQ, Behaviour, Emotion, QLearning
from sb3_affect.agents.baselines import Boltzmann, DecayingEpsilonGreedy, OptimisticQLearning, SpeedEpsilonGreedy, UCBQLearning
from sb3_affect.engine.simulation import simulate
from sb3_affect.kernel.moving_batch import moving_inputs, run_moving
from sb3_affect.kernel.mt19937 import state_from_rng
from sb3_affect.kernel.pcg64 import integers, random01, seeded_state, state_from_generator, state_to_generator

MOVING = "sb3_affect/MovingPursuit-v0"
SMALL = {"size": 5, "start": (0, 0), "prey_start": (2, 2)}
SEEDS = list(range(40))
TABLE = {
    Emotion.JOY: Behaviour(False, (0, 1, 2)),
    Emotion.SADNESS: Behaviour(True, (1,)),
    Emotion.FEAR: Behaviour(True, (2, 0)),
    Emotion.ANGER: Behaviour(True, (1, 2, 3)),
}

# (id, agent class, agent kwargs, env kwargs, episodes)
CASES: list[tuple[str, type, dict[str, Any], dict[str, Any], int]] = [
    ("qlearning-random", QLearning, {"exploration_rate": 0.1}, {**SMALL, "prey": "random"}, 8),
    ("qlearning-evade-fast", QLearning, {"learning_rate": 0.5}, {**SMALL, "prey": "evade", "prey_speed": 0.9}, 8),
    ("qlearning-static", QLearning, {"exploration_rate": 0.3}, {**SMALL, "prey": "static"}, 8),
    ("affectq-random", AffectQ, {}, {**SMALL, "prey": "random"}, 8),
    ("affectq-evade", AffectQ, {}, {**SMALL, "prey": "evade"}, 8),
    ("affectq-valence-remaining-decisions", AffectQ, {"comparison": "valence", "act": "remaining", "units": "decisions"},
     {**SMALL, "prey": "random"}, 8),
    ("affectq-optimistic-step-reward", AffectQ, {"personality": "optimistic"},
     {**SMALL, "prey": "random", "step_reward": -1.0}, 8),
    # (this agent feels joy at every decision and never catches the prey: each episode ends at its cap, kept small)
    ("affectq-table-jump-tie-first", AffectQ,
     {"behaviour_table": TABLE, "multi_cell": "jump", "tie_break": "first", "max_episode_decisions": 300},
     {**SMALL, "prey": "evade", "prey_speed": 0.4}, 8),
    ("affectq-time-limit-cap", AffectQ, {"max_episode_decisions": 30},
     {**SMALL, "prey": "random", "max_episode_steps": 25}, 8),
    ("affectq-obstacles", AffectQ, {}, {**SMALL, "prey": "evade", "obstacles": [(1, 1), (2, 1), (3, 3)]}, 8),
    ("affectq-maze", AffectQ, {"max_episode_decisions": 300}, {"maze": "wall", "prey": "random"}, 3),
    ("decaying", DecayingEpsilonGreedy, {"exploration_decay_episodes": 4}, {**SMALL, "prey": "random"}, 8),
    ("boltzmann", Boltzmann, {"temperature": 2.0}, {**SMALL, "prey": "evade"}, 8),
    ("ucb", UCBQLearning, {"exploration_coef": 3.0}, {**SMALL, "prey": "random"}, 8),
    ("optimistic", OptimisticQLearning, {}, {**SMALL, "prey": "random"}, 8),
    ("speed", SpeedEpsilonGreedy, {"speeds": (0, 1, 2)}, {**SMALL, "prey": "evade"}, 8),
    ("speed-jump", SpeedEpsilonGreedy, {"speeds": (1, 2), "multi_cell": "jump"}, {**SMALL, "prey": "random"}, 8),
]  # fmt: skip


@njit(cache=False)
def _draws(pcg: np.ndarray, ops: np.ndarray, out: np.ndarray) -> None:
    for i in range(ops.shape[0]):
        out[i] = random01(pcg) if ops[i] == 0 else integers(pcg, ops[i])


@pytest.mark.parametrize("seed", [0, 1, 12345, 2**40])
def test_pcg64_port_draws_what_numpy_draws(seed: int) -> None:
    ops = np.random.RandomState(seed % 2**32).randint(0, 7, size=5000)
    ops[::97] = 3_000_000_000  # a large bound: rejections happen
    generator = np.random.Generator(np.random.PCG64(seed))
    expected = np.array([generator.random() if n == 0 else float(generator.integers(int(n))) for n in ops])
    pcg = seeded_state(seed)
    out = np.empty(len(ops))
    _draws(pcg, ops, out)
    assert np.array_equal(out, expected)
    assert np.array_equal(pcg, state_from_generator(generator))
    other = np.random.Generator(np.random.PCG64(0))
    state_to_generator(other, pcg)
    assert other.bit_generator.state == generator.bit_generator.state


def _python_run(cls: type, kwargs: dict[str, Any], env_kwargs: dict[str, Any], seed: int, episodes: int) -> Any:
    model = cls("Grid", gym.make(MOVING, **env_kwargs), seed=seed, engine="python", **kwargs)
    model.learn(episodes * model.max_episode_decisions, callback=StopTrainingOnMaxEpisodes(episodes))
    return model


@pytest.mark.slow
@pytest.mark.parametrize("case", CASES, ids=[c[0] for c in CASES])
def test_moving_kernel_equals_python(case: tuple[str, type, dict[str, Any], dict[str, Any], int]) -> None:
    _, cls, kwargs, env_kwargs, episodes = case
    frames = []
    for seed in SEEDS:
        python = _python_run(cls, kwargs, env_kwargs, seed, episodes)
        template = cls("Grid", gym.make(MOVING, **env_kwargs), seed=seed, **kwargs)
        run = run_moving(moving_inputs(template.compiled_settings(), template.single_env(), episodes), [seed], episodes)
        assert np.array_equal(run.q, python.q_table), f"seed {seed}: Q-table"
        assert np.array_equal(run.mt, state_from_rng(python._rng)[0]), f"seed {seed}: the agent's generator"
        env_generator = python.single_env().unwrapped.np_random
        assert np.array_equal(run.pcg, state_from_generator(env_generator)), f"seed {seed}: the env's generator"
        if cls is AffectQ:
            assert run.dist.tolist() == python.emotion_callback.appraiser.known.distance, f"seed {seed}: known map"
        frame = python.episode_log
        frame.insert(0, "seed", seed)
        frames.append(frame)
    expected = pd.concat(frames, ignore_index=True)
    batch = simulate(cls, kwargs, MOVING, env_kwargs, SEEDS, episodes, engine="compiled")
    pd.testing.assert_frame_equal(batch, expected)
    assert len(expected) == len(SEEDS) * episodes


def test_simulate_by_name_runs_moving_prey_on_the_kernel_without_a_model() -> None:
    env_kwargs = {**SMALL, "prey": "evade"}
    compiled = simulate("AffectQ", {}, MOVING, env_kwargs, [3, 4], 6)
    python = simulate("AffectQ", {}, MOVING, env_kwargs, [3, 4], 6, engine="python")
    pd.testing.assert_frame_equal(compiled, python)
    assert compiled["optimal"].isna().all() and compiled["greedy_optimal"].isna().all()
    assert len(simulate("AffectQ", {}, MOVING, env_kwargs, [], 6)) == 0
