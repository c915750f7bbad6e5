"""Bad arguments are refused at construction, naming the argument, the value and what is allowed."""

from __future__ import annotations

import gymnasium as gym
import pytest

from sb3_affect import AffectQ, QLearning
from sb3_affect.envs import GridPursuitEnv

ENV_ID = "sb3_affect/GridPursuit-v0"


class MultiDiscreteObs(gym.Env):
    observation_space = gym.spaces.MultiDiscrete([3, 3])
    action_space = gym.spaces.Discrete(4)


@pytest.mark.parametrize(
    ("cls", "kwargs", "error", "words"),
    [
        (QLearning, {"seed": "7"}, TypeError, ["seed", "'7'"]),
        (QLearning, {"seed": 1.5}, TypeError, ["seed", "1.5"]),
        (QLearning, {"learning_rate": float("nan")}, ValueError, ["learning_rate=nan", "(0, 1]"]),
        (QLearning, {"learning_rate": 1.5}, ValueError, ["learning_rate=1.5", "(0, 1]"]),
        (QLearning, {"gamma": -0.1}, ValueError, ["gamma=-0.1", "[0, 1]"]),
        (QLearning, {"q_init": float("inf")}, ValueError, ["q_init=inf"]),
        (QLearning, {"exploration_rate": -0.2}, ValueError, ["exploration_rate=-0.2", "[0, 1]"]),
        (QLearning, {"max_episode_decisions": -5}, ValueError, ["max_episode_decisions=-5", "in [1, 1e+15]"]),
        (QLearning, {"max_episode_decisions": 10.0}, TypeError, ["max_episode_decisions", "10.0"]),
        (AffectQ, {"personality": "grumpy"}, ValueError, ["personality", "grumpy"]),
        (AffectQ, {"behaviour_table": [1, 2]}, TypeError, ["behaviour_table", "list"]),
        (AffectQ, {"emotion_callback": "joy"}, TypeError, ["emotion_callback", "str"]),
    ],
)
def test_algorithm_arguments(cls: type, kwargs: dict, error: type[Exception], words: list[str]) -> None:
    with pytest.raises(error) as info:
        cls("Grid", ENV_ID, **kwargs)
    for word in words:
        assert word in str(info.value), (word, str(info.value))


@pytest.mark.parametrize("cls", [QLearning, AffectQ])
def test_unsupported_spaces_name_what_is_supported(cls: type) -> None:
    with pytest.raises(TypeError, match=r"MultiDiscrete.*Discrete observation space"):
        cls("Grid", MultiDiscreteObs())
    with pytest.raises(TypeError, match=r"Box.*Discrete observation space"):
        cls("Grid", "CartPole-v1")


@pytest.mark.parametrize(
    ("kwargs", "error", "words"),
    [
        ({"obstacles": [(20, 1)]}, ValueError, ["obstacles[0]=(20, 1)", "outside"]),
        ({"obstacles": "#"}, TypeError, ["obstacles", "list of (row, col)"]),
        ({"start": (0.5, 0)}, TypeError, ["start", "integers"]),
        ({"start": (0, 0, 0)}, TypeError, ["start", "(row, col)"]),
        ({"size": True}, TypeError, ["size", "integer"]),
        ({"step_reward": "x"}, TypeError, ["step_reward", "finite number"]),
    ],
)
def test_env_arguments(kwargs: dict, error: type[Exception], words: list[str]) -> None:
    with pytest.raises(error) as info:
        GridPursuitEnv(**kwargs)
    for word in words:
        assert word in str(info.value), (word, str(info.value))
