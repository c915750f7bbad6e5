"""
The deep agents' surface: a ``position`` that does not fit the env refused at construction (or, for a callable's
values, on the first step) with one line; the controls exported beside ``AffectDQN``; ``model.episode_log`` on every
agent that feels; the mixin on a user's own algorithm, as the docs show it.
"""

from __future__ import annotations

import math
from typing import Any

import gymnasium as gym
import pytest
from stable_baselines3 import DQN
from stable_baselines3.common.env_util import make_vec_env

import sb3_affect
from sb3_affect import AffectDQN, AffectQ, AffectQRDQN, EmotionCallback
from sb3_affect.core.episode_log import EPISODE_COLUMNS


def one_line(make: Any, error: type, text: str) -> None:
    with pytest.raises(error) as raised:
        make()
    message = str(raised.value)
    assert text in message and "\n" not in message, message


@pytest.mark.parametrize("agent", [AffectDQN, AffectQRDQN])
def test_a_position_that_does_not_fit_the_env_is_refused_at_construction(agent: type) -> None:
    one_line(lambda: agent("MlpPolicy", "FrozenLake-v1", position="multidiscrete"), TypeError,
             "position='multidiscrete' needs a multidiscrete observation space, got Discrete(16)")
    one_line(lambda: agent("MlpPolicy", "sb3_affect/GridPursuit-v0", position="minigrid"), ValueError,
             "position='minigrid': the env has no agent_pos")
    one_line(lambda: agent("MlpPolicy", "CartPole-v1"), TypeError, "Box observations have no cells and no position= hook")
    agent("MlpPolicy", "CartPole-v1", emotion_callback=EmotionCallback(emotion_rule=lambda appraisal: 0))  # needs no map


def test_the_emotion_callback_given_as_settings_builds_the_agents_own() -> None:
    settings = {"comparison": "valence", "act": "remaining", "order": "act-first"}
    first, second = (AffectDQN("MlpPolicy", "FrozenLake-v1", emotion_callback=settings) for _ in range(2))
    assert first.emotion_callback is not second.emotion_callback
    callback = first.emotion_callback
    assert (callback.comparison, callback.act, callback.order) == ("valence", "remaining", "act-first")
    one_line(lambda: AffectDQN("MlpPolicy", "FrozenLake-v1", emotion_callback={"goal": "print"}), ValueError,
             "emotion_callback.goal can not be given as data")
    one_line(lambda: AffectDQN("MlpPolicy", "FrozenLake-v1", emotion_callback={"order": "sideways"}), ValueError,
             "order='sideways'")


@pytest.mark.parametrize("bad", [math.nan, (1, math.inf), [1, 2]])
def test_a_position_callable_returning_no_cell_is_refused_on_the_first_step(bad: Any) -> None:
    model = AffectDQN("MlpPolicy", "CartPole-v1", learning_starts=0, position=lambda obs, info: bad)
    one_line(lambda: model.learn(8), ValueError, "which is not a cell; a cell is a hashable value without NaN")
    assert model.num_timesteps == 0  # refused when training starts, before a step


def test_the_controls_are_exported_beside_affect_dqn() -> None:
    from sb3_affect.agents import deep_controls

    for name in ("EzGreedyDQN", "SpeedEpsilonGreedyDQN", "EzGreedyExploration", "SpeedEpsilonGreedyExploration"):
        assert getattr(sb3_affect, name) is getattr(deep_controls, name) and name in sb3_affect.__all__


def test_every_agent_that_feels_keeps_episode_log() -> None:
    tabular = AffectQ("Grid", gym.make("sb3_affect/GridPursuit-v0", size=5, goal=(2, 2)), seed=0).learn(300)
    deep = AffectDQN("MlpPolicy", make_vec_env("FrozenLake-v1", n_envs=2, seed=0), learning_starts=0, seed=0).learn(300)
    for model in (tabular, deep):
        log = model.episode_log
        assert list(log.columns[: len(EPISODE_COLUMNS)]) == list(EPISODE_COLUMNS) and len(log) > 0
    assert deep.episode_log.equals(deep.emotion_callback.episode_log)


def test_the_docs_mixin_example_runs() -> None:
    """docs/deep_agents.md, 'The mixin on your own algorithm', with its options filled in."""
    from sb3_affect import AffectiveExploration

    class MyDQN(DQN):
        """A user's DQN variant."""

    class AffectMyDQN(AffectiveExploration, MyDQN):
        """MyDQN exploring with the emotions."""

    model = AffectMyDQN("MlpPolicy", "FrozenLake-v1", behaviour_table="table-iii", position="discrete", wait_action=None,
                        learning_starts=0, seed=0).learn(200)
    assert model._decisions > 0 and len(model.episode_log) > 0
