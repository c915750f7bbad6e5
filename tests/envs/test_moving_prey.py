"""MovingPursuit: a prey that random-walks or evades; the joint observation; capture; tabular agents improve."""

from __future__ import annotations

import itertools
import math

import gymnasium as gym
import numpy as np
import pytest
from stable_baselines3.common.callbacks import StopTrainingOnMaxEpisodes

import sb3_affect  # noqa: F401  (registers the envs)
from sb3_affect import AffectQ, QLearning
from sb3_affect.envs.moving_pursuit import MovingPursuitEnv

ENV_ID = "sb3_affect/MovingPursuit-v0"


def captured(env: MovingPursuitEnv, observation: int) -> bool:
    """Whether an observation is a capture: the hunter and the prey in one cell (``decode``)."""
    hunter, prey = env.decode(observation)
    return hunter == prey


def random_episode(env: MovingPursuitEnv, seed: int, steps: int = 400) -> list[tuple[int, bool]]:
    obs, _ = env.reset(seed=seed)
    rng = np.random.default_rng(seed)
    out = [(obs, False)]
    for _ in range(steps):
        obs, reward, terminated, truncated, _ = env.step(int(rng.integers(4)))
        assert not truncated
        assert env.observation_space.contains(obs)
        out.append((obs, terminated))
        if terminated:
            assert reward == env.goal_reward and captured(env, obs)
            break
        assert reward == 0.0 and not captured(env, obs)
    return out


@pytest.mark.parametrize("prey", ["random", "evade"])
def test_prey_stays_on_the_grid_and_moves_one_cell_at_most(prey: str) -> None:
    env = MovingPursuitEnv(size=6, start=(0, 0), prey_start=(3, 3), obstacles=[(2, 2)], prey=prey, prey_speed=0.7)
    moved = 0
    for seed in range(5):
        path = random_episode(env, seed)
        for (a, _), (b, _) in itertools.pairwise(path):
            (_, prey_a), (_, prey_b) = env.decode(a), env.decode(b)
            assert all(0 <= v < 6 for v in prey_b) and prey_b != (2, 2)
            assert abs(prey_a[0] - prey_b[0]) + abs(prey_a[1] - prey_b[1]) <= 1
            moved += prey_a != prey_b
    assert moved > 0


def test_observation_is_hunter_times_prey() -> None:
    env = gym.make(ENV_ID).unwrapped
    assert env.observation_space.n == 225 * 225
    obs, info = env.reset(seed=0)
    assert obs == 0 * 225 + 6 * 15 + 6 and info["prey"] == (6, 6)
    assert env.decode(obs) == ((0, 0), (6, 6))
    assert env.capture_distance == 12


def test_capture_terminates_and_static_prey_never_moves() -> None:
    env = MovingPursuitEnv(size=4, start=(0, 0), prey_start=(0, 2), prey="static")
    env.reset(seed=0)
    obs, reward, terminated, _, _ = env.step(3)
    assert not terminated and env.decode(obs) == ((0, 1), (0, 2))
    obs, reward, terminated, _, _ = env.step(3)
    assert terminated and reward == 100.0 and env.decode(obs) == ((0, 2), (0, 2))
    assert env.optimal_capture(2, True) and not env.optimal_capture(3, True) and not env.optimal_capture(2, False)


def test_evading_prey_moves_away() -> None:
    env = MovingPursuitEnv(size=7, start=(3, 2), prey_start=(3, 3), prey="evade", prey_speed=1.0)
    env.reset(seed=0)
    obs, _, terminated, _, _ = env.step(0)  # hunter up to (2, 2); the prey flees
    (hunter, prey) = env.decode(obs)
    assert not terminated and abs(hunter[0] - prey[0]) + abs(hunter[1] - prey[1]) == 3


def test_prey_never_steps_onto_the_hunter() -> None:
    env = MovingPursuitEnv(size=2, start=(0, 0), prey_start=(1, 1), prey="random", prey_speed=1.0)
    for seed in range(20):
        env.reset(seed=seed)
        obs, _, terminated, _, _ = env.step(0)  # bump: the hunter stays at (0, 0)
        assert terminated or not captured(env, obs)


def test_the_env_is_seeded() -> None:
    a = random_episode(MovingPursuitEnv(size=5, prey_start=(2, 2)), 3)
    b = random_episode(MovingPursuitEnv(size=5, prey_start=(2, 2)), 3)
    assert a == b


def test_invalid_options() -> None:
    with pytest.raises(ValueError, match="prey="):
        MovingPursuitEnv(prey="teleport")
    with pytest.raises(ValueError, match="prey_speed"):
        MovingPursuitEnv(prey_speed=1.5)
    with pytest.raises(ValueError, match="unreachable"):
        MovingPursuitEnv(size=3, start=(0, 0), prey_start=(2, 2), obstacles=[(0, 1), (1, 0), (1, 1)])


def test_maze_option() -> None:
    env = gym.make(ENV_ID, maze="wall").unwrapped
    assert env.capture_distance == 24 and env.start == (0, 0) and env.prey_start == (6, 6) and len(env.obstacles) == 12


@pytest.mark.parametrize("cls", [QLearning, AffectQ])
def test_tabular_agent_improves_against_moving_prey(cls: type) -> None:
    improved = 0
    for seed in range(3):
        env = gym.make(ENV_ID, size=5, start=(0, 0), prey_start=(2, 2), prey="random", prey_speed=0.5)
        model = cls("Grid", env, seed=seed)
        model.learn(10**8, callback=StopTrainingOnMaxEpisodes(300))
        log = model.episode_log
        assert not log["truncated"].any()
        assert math.isnan(log["optimal"].iloc[0]) and math.isnan(log["greedy_optimal"].iloc[0])
        improved += log["decisions"].tail(60).mean() < 0.8 * log["decisions"].head(60).mean()
    assert improved >= 2
