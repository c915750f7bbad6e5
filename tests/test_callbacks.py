"""EmotionCallback observing a real SB3 DQN (not a mock) on GridPursuit."""

from __future__ import annotations

import gymnasium as gym
import pandas as pd
import torch as th
from stable_baselines3 import DQN
from stable_baselines3.common.callbacks import CallbackList, StopTrainingOnMaxEpisodes
from stable_baselines3.common.logger import configure

from sb3_affect import EPISODE_COLUMNS, EmotionCallback


def test_emotion_callback_on_dqn_logs_a_profile(tmp_path) -> None:
    th.set_num_threads(1)
    env = gym.make("sb3_affect/GridPursuit-v0", size=5, goal=(2, 2), max_episode_steps=60)
    model = DQN("MlpPolicy", env, learning_starts=50, train_freq=4, seed=0, policy_kwargs={"net_arch": [32]})
    model.set_logger(configure(str(tmp_path), ["csv"]))
    emotions = EmotionCallback()
    model.learn(3000, callback=CallbackList([emotions, StopTrainingOnMaxEpisodes(12)]), log_interval=1)
    log = emotions.episode_log
    assert tuple(log.columns) == EPISODE_COLUMNS
    assert len(log) == 12
    assert (log[["joy", "sadness", "fear", "anger"]].sum(axis=1) == log.decisions).all()
    assert (log.cells == log.decisions).all()
    assert ((log.reward == 100.0) == ~log.truncated).all() and (log.decisions[log.truncated] == 60).all()
    assert (log.optimal == ((log.cells == 4) & ~log.truncated)).all()
    assert log.norm.isna().iloc[0] and log.norm.iloc[1] == log.cells.iloc[0]
    assert log.random_moves.isna().all()
    assert log.greedy_optimal.dtype == bool
    assert log.decisions.sum() == model.num_timesteps
    # the logger got the affect keys next to DQN's own
    frame = pd.read_csv(tmp_path / "progress.csv")
    for key in ("affect/joy", "affect/anger", "affect/norm", "rollout/exploration_rate", "rollout/ep_len_mean"):
        assert key in frame.columns, key


def test_emotion_callback_refuses_non_discrete_observations() -> None:
    model = DQN("MlpPolicy", "CartPole-v1", learning_starts=10)
    try:
        model.learn(20, callback=EmotionCallback())
    except TypeError as error:
        assert "Discrete observation space" in str(error)
    else:  # pragma: no cover
        raise AssertionError("EmotionCallback accepted a Box observation space")
