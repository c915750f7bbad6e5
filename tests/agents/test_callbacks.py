"""EmotionCallback observing real SB3 algorithms (not mocks): GridPursuit, CartPole, a (row, column) grid, a VecEnv."""

from __future__ import annotations

import itertools
import math

import gymnasium as gym
import numpy as np
import pandas as pd
import pytest
import torch as th
from stable_baselines3 import DQN, PPO
from stable_baselines3.common.callbacks import CallbackList, StopTrainingOnMaxEpisodes
from stable_baselines3.common.env_util import make_vec_env
from stable_baselines3.common.logger import configure

from sb3_affect import Emotion, EmotionCallback
from sb3_affect.agents.callbacks import EMOTION_CALLBACK_COLUMNS


def test_emotion_callback_on_dqn_logs_a_profile(tmp_path) -> None:
    th.set_num_threads(1)
    env = gym.make("sb3_affect/GridPursuit-v0", size=5, goal=(2, 2), max_episode_steps=60)
    model = DQN("MlpPolicy", env, learning_starts=50, train_freq=4, seed=0, policy_kwargs={"net_arch": [32]})
    model.set_logger(configure(str(tmp_path), ["csv"]))
    emotions = EmotionCallback()
    model.learn(3000, callback=CallbackList([emotions, StopTrainingOnMaxEpisodes(12)]), log_interval=1)
    log = emotions.episode_log
    assert tuple(log.columns) == EMOTION_CALLBACK_COLUMNS
    assert len(log) == 12 and (log.env == 0).all()
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


def test_table_ii_on_observations_without_cells_is_refused_naming_what_works() -> None:
    for comparison in ("literal", "valence"):
        model = DQN("MlpPolicy", "CartPole-v1", learning_starts=10)
        with pytest.raises(TypeError, match=r"Box observations have no cells and no position= hook.*Give position="
                                            r"'minigrid'.*or an emotion_rule.*Spaces with a map: Discrete, and MultiDiscrete"):
            model.learn(20, callback=EmotionCallback(comparison=comparison))


def past_norm(appraisal) -> Emotion:
    return Emotion.JOY if appraisal is None or appraisal.exp1 <= appraisal.norm else Emotion.FEAR


def test_a_map_free_rule_on_box_observations_counts_every_decision(tmp_path) -> None:
    env = gym.make("CartPole-v1", max_episode_steps=30)
    model = PPO("MlpPolicy", env, n_steps=64, n_epochs=1, seed=0, policy_kwargs={"net_arch": [8]})
    emotions = EmotionCallback(emotion_rule=past_norm)
    model.learn(640, callback=emotions)
    log = emotions.episode_log
    assert (log[["joy", "sadness", "fear", "anger"]].sum(axis=1) == log.decisions).all()
    # fear: exactly the decisions taken after the episode ran past the norm (the first is appraised at elapsed 0)
    past = [max(0, d - math.floor(n) - 1) if n == n else 0 for d, n in zip(log.decisions, log.norm)]
    assert log.fear.tolist() == past and log.fear.sum() > 0


def test_multidiscrete_observations_get_a_map_and_vecenv_lanes_their_own_appraisal(tmp_path) -> None:
    """A grid seen as (row, column): the flat cell index gives the same map as the Discrete grid."""

    class RowColumn(gym.ObservationWrapper):
        def __init__(self, env: gym.Env) -> None:
            super().__init__(env)
            self.size = env.unwrapped.size
            self.observation_space = gym.spaces.MultiDiscrete([self.size, self.size])

        def observation(self, observation):
            return np.array(divmod(int(observation), self.size))

    kwargs = {"size": 4, "goal": (2, 2), "max_episode_steps": 40}
    env = make_vec_env("sb3_affect/GridPursuit-v0", n_envs=2, seed=0, env_kwargs=kwargs, wrapper_class=RowColumn)
    model = DQN("MlpPolicy", env, learning_starts=20, seed=0, policy_kwargs={"net_arch": [8]})
    model.set_logger(configure(str(tmp_path), ["csv"]))
    emotions = EmotionCallback()
    model.learn(800, callback=emotions, log_interval=1)
    log = emotions.episode_log
    assert set(log.env) == {0, 1}
    lanes = emotions._lanes
    assert lanes[0].appraiser is emotions.appraiser and lanes[1].appraiser is not lanes[0].appraiser
    for index, lane in enumerate(lanes):  # each env's norm fits that env's own finished episodes
        assert lane.appraiser.fit.values == log.cells[log.env == index].astype(float).tolist()
        assert 2 * 4 + 2 in lane.appraiser.known.goals  # the goal cell (2, 2), flattened
    written = pd.read_csv(tmp_path / "emotion_episodes.csv")
    assert tuple(written.columns) == EMOTION_CALLBACK_COLUMNS and len(written) == len(log)
    # affect/* at each dump: the mean over the last episodes (the stats window), as rollout/ep_len_mean
    progress = pd.read_csv(tmp_path / "progress.csv").dropna(subset=["affect/joy"])
    last = progress.iloc[-1]
    window = log.tail(model._stats_window_size)
    assert last["affect/joy"] == pytest.approx((window.joy / window.decisions).mean())
    assert last["rollout/ep_len_mean"] == pytest.approx(window.decisions.mean())


def test_no_goal_ever_seen_warns_once_saying_how_to_pass_goal() -> None:
    from sb3_contrib.common.envs import InvalidActionEnvDiscrete

    env = gym.wrappers.TimeLimit(InvalidActionEnvDiscrete(dim=20, n_invalid_actions=10), max_episode_steps=5)
    model = DQN("MlpPolicy", env, learning_starts=10, seed=0, policy_kwargs={"net_arch": [8]})
    message = r"none of the first 3 episodes reached the goal.*pass EmotionCallback\(goal="
    with pytest.warns(RuntimeWarning, match=message) as record:
        model.learn(200, callback=EmotionCallback(warn_after=3))
    assert len([w for w in record if "reached the goal" in str(w.message)]) == 1
    with pytest.raises(ValueError, match="warn_after=0 must be an integer >= 1"):
        EmotionCallback(warn_after=0)


def test_the_hooks_drive_an_agent_of_ones_own_with_no_sb3_model() -> None:
    """A corridor 0 - 1 - ... - 5 (the goal at 5) walked by a user's own loop through the documented hooks alone."""
    callback = EmotionCallback()
    callback.bind(6)
    walks = [[0, 1, 0, 1, 2, 3, 4, 5], [0, 1, 2, 3, 4, 5]]  # a detour of 7 moves, then the shortest path of 5
    felt, results = [], []
    for walk in walks:
        callback.begin_episode()
        for s, s2 in itertools.pairwise(walk):
            felt.append(callback.feel(s))
            assert callback.emotion == felt[-1]  # what an agent reads to steer its next decision
            callback.observe(s, s2, s2 == 5)
        results.append(callback.end_episode(True))
    (first_counts, first_norm), (counts, norm) = results
    assert first_counts == [7, 0, 0, 0] and first_norm != first_norm  # nothing to appraise yet: joy, no norm
    # then norm 7 (the first episode), act 5 (the known path): act < norm and exp1 = 7 > act: anger at every step
    assert norm == 7.0 and counts == [0, 0, 0, 5] and felt[7:] == [Emotion.ANGER] * 5
    assert callback.appraiser is not None and callback.appraiser.known.goals == {5}


def test_the_window_records_again_only_after_a_new_row_or_a_dump() -> None:
    from sb3_affect.agents.callbacks import WindowMeans, flat_array

    logger = configure(None, [])
    window = WindowMeans(2, size=3)
    keys = ("affect/a", "affect/b")
    window.record(logger, keys, again=False)  # no row yet: NaN means are left out
    assert logger.name_to_value == {}
    window.append([1.0, math.nan])
    window.record(logger, keys, again=False)
    assert logger.name_to_value == {"affect/a": 1.0}
    logger.name_to_value["affect/a"] = -1.0  # nothing new: not recorded again
    window.record(logger, keys, again=False)
    assert logger.name_to_value["affect/a"] == -1.0
    window.record(logger, keys)  # asked to: recorded
    assert logger.name_to_value["affect/a"] == 1.0
    logger.dump()  # the logger wrote them out: recorded again at the next rollout end
    window.record(logger, keys, again=False)
    assert logger.name_to_value == {"affect/a": 1.0}
    window.append([3.0, 2.0])
    window.record(logger, keys, again=False)
    assert logger.name_to_value == {"affect/a": 2.0, "affect/b": 2.0}
    # a VecEnv's per-env array: a 1-d array of the asked dtype is not copied; anything else is converted
    dones = np.array([True, False])
    assert flat_array(dones, bool) is dones
    np.testing.assert_array_equal(flat_array([[1], [0]], bool), dones)
    assert flat_array(np.array([[0.5], [1.0]], dtype=np.float32)).tolist() == [0.5, 1.0]
