"""GridPursuit: dynamics, rewards, validation, rendering, SB3's env checker."""

from __future__ import annotations

import warnings

import gymnasium as gym
import numpy as np
import pytest
from stable_baselines3.common.env_checker import check_env

from sb3_affect.envs import MOVES, GridPursuitEnv
from sb3_affect.envs.grid_pursuit import DOWN, LEFT, RIGHT, UP


def test_registered_defaults_match_the_paper(grid_env: gym.Env) -> None:
    env = grid_env.unwrapped
    assert isinstance(env, GridPursuitEnv)
    assert (env.size, env.start, env.goal) == (15, (0, 0), (6, 6))
    assert env.observation_space == gym.spaces.Discrete(225)
    assert env.action_space == gym.spaces.Discrete(4)
    assert env.shortest_path_length == 12
    obs, info = grid_env.reset(seed=0)
    assert obs == 0 and info["cell"] == (0, 0)


def test_moves_walls_and_goal() -> None:
    env = GridPursuitEnv(size=3, start=(0, 0), goal=(2, 2))
    env.reset()
    obs, reward, terminated, truncated, info = env.step(UP)  # off the grid: stays put
    assert (obs, reward, terminated, truncated, info["moved"]) == (0, 0.0, False, False, False)
    obs, *_ = env.step(LEFT)
    assert obs == 0
    obs, *_ = env.step(RIGHT)
    assert obs == 1
    obs, *_ = env.step(DOWN)
    assert obs == 4
    obs, reward, terminated, *_ = env.step(DOWN)
    assert (obs, reward, terminated) == (7, 0.0, False)
    obs, reward, terminated, truncated, info = env.step(RIGHT)
    assert (obs, reward, terminated, truncated, info["cell"]) == (8, 100.0, True, False, (2, 2))


def test_obstacles_block_and_distances_route_around_them() -> None:
    env = GridPursuitEnv(size=3, start=(0, 0), goal=(0, 2), obstacles=[(0, 1), (1, 1)])
    env.reset()
    obs, *_ = env.step(RIGHT)  # into an obstacle: stays put
    assert obs == 0
    assert env.shortest_path_length == 6  # down, down, right, right, up, up


def test_moves_are_defined_once() -> None:
    env = GridPursuitEnv()
    for s in range(225):
        r, c = divmod(s, 15)
        for a, (dr, dc) in enumerate(MOVES):
            rr, cc = r + dr, c + dc
            expected = rr * 15 + cc if 0 <= rr < 15 and 0 <= cc < 15 else s
            assert env.transitions[s][a] == expected


def test_random_walk_reward_only_at_goal() -> None:
    env = GridPursuitEnv(size=5, goal=(2, 3))
    rng = np.random.default_rng(1)
    env.reset()
    for _ in range(2000):
        obs, reward, terminated, _, _ = env.step(int(rng.integers(4)))
        assert 0 <= obs < 25
        assert (reward == 100.0) == terminated == (obs == env.goal_state)
        if terminated:
            env.reset()


def test_check_env_passes_without_warnings(grid_env: gym.Env) -> None:
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        check_env(GridPursuitEnv())
        check_env(grid_env)


def test_unsupported_render_mode_is_named() -> None:
    with pytest.raises(ValueError, match=r"render_mode='human' is not supported; use None, 'ansi' or 'rgb_array'"):
        GridPursuitEnv(render_mode="human")


def test_render_modes() -> None:
    env = GridPursuitEnv(size=4, goal=(1, 2), obstacles=[(3, 3)], render_mode="ansi")
    env.reset()
    text = env.render()
    assert isinstance(text, str)
    assert text.splitlines()[0].split() == ["H", ".", ".", "."]
    assert "P" in text.splitlines()[1] and "#" in text.splitlines()[3]
    rgb = GridPursuitEnv(size=4, goal=(1, 1), render_mode="rgb_array")
    rgb.reset()
    img = rgb.render()
    assert isinstance(img, np.ndarray) and img.shape == (64, 64, 3) and img.dtype == np.uint8


@pytest.mark.parametrize(
    ("kwargs", "error", "words"),
    [
        ({"goal": (15, 2)}, ValueError, ["goal=(15, 2)", "outside", "[0, 14]"]),
        ({"start": (-1, 0)}, ValueError, ["start=(-1, 0)", "outside"]),
        ({"start": (3, 3), "goal": (3, 3)}, ValueError, ["start=(3, 3)", "equals goal"]),
        ({"obstacles": [(0, 0)]}, ValueError, ["start=(0, 0)", "obstacle"]),
        ({"obstacles": [(6, 6)]}, ValueError, ["goal=(6, 6)", "obstacle"]),
        ({"obstacles": [(5, 6), (7, 6), (6, 5), (6, 7)]}, ValueError, ["unreachable", "wall it off"]),
        ({"size": 1}, ValueError, ["size=1", ">= 2"]),
        ({"size": 7.5}, TypeError, ["size", "integer", "7.5"]),
        ({"goal": "66"}, TypeError, ["goal", "(row, col)"]),
        ({"goal_reward": 0}, ValueError, ["goal_reward=0", "> 0"]),
        ({"goal_reward": float("nan")}, TypeError, ["goal_reward", "finite"]),
    ],
)
def test_invalid_arguments_are_named(kwargs: dict, error: type[Exception], words: list[str]) -> None:
    with pytest.raises(error) as info:
        gym.make("sb3_affect/GridPursuit-v0", **kwargs)
    for word in words:
        assert word in str(info.value)
